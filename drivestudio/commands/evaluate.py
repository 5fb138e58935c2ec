"""drivestudio evaluate --data DIR --model CKPT [--model CKPT ...]: MAE per indicator as seed 002's Table 3."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import UsageError


def register(sub) -> None:
    p = sub.add_parser("evaluate", help="MAE per indicator of trained models, as the paper's Table 3",
                       description="Mean absolute error per indicator of one or more checkpoints on a split of a "
                                   "dataset, one row per model beside the paper's three (Table 3), split by regime "
                                   "(in lane, on marking, overlap) and by lane count, with inference latency and "
                                   "throughput. Writes mae.md, mae.csv, mae_by_regime.csv, mae_by_lanes.csv, "
                                   "speed.csv, mae.png and evaluation.json to --out.")
    p.add_argument("--data", required=True, help="dataset folder written by `drivestudio generate`")
    p.add_argument("--model", required=True, action="append", metavar="CKPT",
                   help="checkpoint written by `drivestudio train` (repeat for several models)")
    p.add_argument("--split", default="test", choices=("train", "val", "test", "all"),
                   help="frames to measure on (default test)")
    p.add_argument("--out", default="out/evaluate", help="folder for the report (default out/evaluate)")
    p.add_argument("--device", default="cpu", help="cpu (default), cuda or cuda:N")
    p.add_argument("--batch-size", type=int, default=32, help="frames per forward pass (default 32)")
    p.add_argument("--workers", type=int, default=0, help="processes decoding frames (default 0)")
    p.add_argument("--latency-frames", type=int, default=100,
                   help="frames timed one at a time for the latency figure (default 100)")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.batch_size < 1 or args.latency_frames < 1 or args.workers < 0:
        raise UsageError("--batch-size and --latency-frames must be at least 1, --workers not negative")
    if args.device.startswith("cuda"):
        import torch
        if not torch.cuda.is_available():
            raise UsageError(f"--device {args.device}: no CUDA device is available here")

    from perception.evaluate import evaluate

    from ..outputs import write_json, write_png, write_text

    ev = evaluate(args.data, args.model, split=args.split, device=args.device, batch_size=args.batch_size,
                  workers=args.workers, latency_frames=args.latency_frames)
    out = Path(args.out)
    for name, content in ev.files.items():
        if isinstance(content, np.ndarray):
            write_png(out / name, content)
        elif isinstance(content, dict):
            write_json(out / name, content)
        else:
            write_text(out / name, content)
    print(ev.markdown)
    print(f"wrote {', '.join(sorted(ev.files))} to {out}/")
    return 0
