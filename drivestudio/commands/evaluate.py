"""drivestudio evaluate --data DIR --model CKPT [--model CKPT ...]: MAE per output; for the highway as Liu and
Wang's Table 3."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from core.files import check_output, check_output_dir
from drivestudio import worlds
from drivestudio.checkpoints import check_checkpoint, check_device
from drivestudio.commands.common import add_device_option
from drivestudio.commands.numbers import count
from drivestudio.outputs import write_json, write_png, write_text
from perception.memory import check_batch


def register(sub) -> None:
    p = sub.add_parser("evaluate", help="MAE per output of trained models (the highway: as Liu and Wang's Table 3)",
                       description="Mean absolute error per output of one or more checkpoints on a split of a "
                                   "dataset of their world, with inference latency and throughput; for the highway "
                                   "one row per model beside Liu and Wang's three (their Table 3), split by regime "
                                   "(in lane, on marking, overlap) and by lane count. Writes mae.md, mae.csv, "
                                   "mae_by_regime.csv, mae_by_lanes.csv, speed.csv, mae.png and evaluation.json.")
    p.add_argument("--data", required=True, help="dataset folder written by `drivestudio generate`")
    p.add_argument("--model", required=True, action="append", metavar="CKPT",
                   help="checkpoint written by `drivestudio train` (repeat for several models)")
    p.add_argument("--split", default="test", choices=("train", "val", "test", "all"),
                   help="frames to measure on (default test)")
    p.add_argument("--out", default="out/evaluate", help="folder for the report (default out/evaluate)")
    add_device_option(p)
    p.add_argument("--batch-size", type=count(1, 4096), default=32,
                   help="samples per forward pass (default 32)")
    p.add_argument("--workers", type=count(0, 64), default=0, help="processes decoding frames (0)")
    p.add_argument("--latency-frames", type=count(1, 100000), default=100,
                   help="samples timed one at a time for the latency figure (default 100)")
    p.set_defaults(func=run)


def run(args) -> int:
    from perception.checkpoint import CheckpointError  # lazy: torch
    from perception.evaluate import REPORT_FILES, evaluate  # lazy: torch, pyarrow
    from perception.shards import Dataset  # lazy: pyarrow (80 ms) only when a dataset is read

    check_device(args.device)
    check_output_dir(args.out)
    for name in REPORT_FILES:   # each file of the report, not only the folder: before any model is evaluated
        check_output(Path(args.out) / name, None, "report file")
    world = Dataset(Path(args.data)).world
    for path in args.model:   # every model, before any is evaluated: intact, finite, of the dataset's world
        try:
            spec = check_checkpoint(path, world)
        except CheckpointError as e:
            raise CheckpointError(f"{e} (the dataset {args.data} is of the {world} world)") from None
        check_batch(args.batch_size, spec["input"])   # before a batch is allocated
    layout = worlds.get(world).evaluation_layout()
    ev = evaluate(args.data, args.model, split=args.split, device=args.device, batch_size=args.batch_size,
                  workers=args.workers, latency_frames=args.latency_frames, layout=layout)
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
