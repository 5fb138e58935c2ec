"""MultiNet's speed (issue 14's targets: Z2Color inference <= 5 ms per data moment at batch 1 on this CPU, closed
loop over the bridge >= 30 Hz; training moments/s reported).

    python bench/bench_multinet.py [--repeats 200] [--seconds 20] [--json F]

1. Inference: a Z2Color MultiNet on one data moment (four 336x188 images, averaged to 12 x 94 x 168 inside the
   model) at batch 1, in PyTorch (inference mode) and through its ONNX export in ONNX Runtime; also batch 32.
2. Training: moments per second of MultiNet's training step (Adadelta, batch 60, gradient clipping), forward and
   backward, on moments already in memory (as perception/multinet.py holds them).
3. Closed loop: `drivestudio drive --world sidewalk --model CKPT` with the network as a driver process over shared
   memory, lock-step at the world's 30 Hz simulated rate, run as fast as it can; the loop rate from metrics.json.
"""
from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def checkpoint(folder: Path) -> Path:
    import torch

    from core import worlds
    from perception.checkpoint import save_checkpoint
    from perception.models import Regressor, make_spec
    torch.manual_seed(0)
    model = Regressor(make_spec("z2color", worlds.get("sidewalk")))
    path = folder / "multinet.pt"
    save_checkpoint(path, {"spec": model.spec, "state_dict": model.state_dict(), "train": {}})
    return path


def _median_ms(fn, repeats: int) -> float:
    for _ in range(5):
        fn()
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return float(np.median(times) * 1e3)


def inference(ckpt: Path, repeats: int) -> dict:
    import torch

    from perception.export import export_onnx
    from perception.predictor import load_predictor
    predict = load_predictor(ckpt)
    rng = np.random.default_rng(0)
    moment = [rng.integers(0, 256, (188, 336, 3), dtype=np.uint8) for _ in range(4)]
    out = {"threads": torch.get_num_threads(),
           "torch_ms_batch1": _median_ms(lambda: predict(moment, "direct"), repeats)}
    batch = [moment] * 32
    out["torch_ms_per_moment_batch32"] = _median_ms(lambda: predict.batch(batch, ["direct"] * 32), 10) / 32
    try:
        import onnxruntime as ort
        onnx = ckpt.with_suffix(".onnx")
        export_onnx(ckpt, onnx)
        sess = ort.InferenceSession(str(onnx), providers=["CPUExecutionProvider"])
        small = np.concatenate([m[::2, ::2] for m in moment], axis=2).transpose(2, 0, 1)[None]   # 12 x 94 x 168
        feed = {"images": np.ascontiguousarray(small), "modes": np.array([0])}
        out["onnx_ms_batch1"] = _median_ms(lambda: sess.run(["outputs"], feed), repeats)
    except ImportError:
        out["onnx_ms_batch1"] = None
    return out


def training(steps: int = 20, batch: int = 60) -> dict:
    import torch

    from core import worlds
    from perception.models import Regressor, make_spec
    from perception.multinet import CLIP, train_loss
    model = Regressor(make_spec("z2color", worlds.get("sidewalk"))).train()
    opt = torch.optim.Adadelta(model.parameters(), lr=1.0)
    x = torch.randint(0, 256, (batch, 12, 94, 168), dtype=torch.uint8)
    m = torch.randint(0, 3, (batch,))
    y = torch.rand(batch, 20)

    def step():
        loss = train_loss(model(x, m), y)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(model.parameters(), CLIP)
        opt.step()

    step()
    t0 = time.perf_counter()
    for _ in range(steps):
        step()
    return {"moments_per_s": round(steps * batch / (time.perf_counter() - t0), 1), "batch": batch}


def closed_loop(ckpt: Path, seconds: float, folder: Path) -> dict:
    out = folder / "drive"
    subprocess.run([sys.executable, "-m", "drivestudio", "drive", "--world", "sidewalk", "--model", str(ckpt),
                    "--operation", "correctional", "--seconds", str(seconds), "--out", str(out)], check=True,
                   capture_output=True)
    m = json.loads((out / "metrics.json").read_text())
    return {"loop_rate_hz": m["loop_rate_hz"], "stage_ms_per_step": m["stage_ms_per_step"]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeats", type=int, default=200, help="timed single-moment inferences (default 200)")
    ap.add_argument("--seconds", type=float, default=20.0, help="simulated seconds of the closed loop (default 20)")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-multinet-") as tmp:
        ckpt = checkpoint(Path(tmp))
        inf = inference(ckpt, args.repeats)
        print(f"Z2Color MultiNet inference, one data moment (4 x 336x188 images), batch 1, {inf['threads']} threads: "
              f"PyTorch {inf['torch_ms_batch1']:.2f} ms, ONNX Runtime "
              + (f"{inf['onnx_ms_batch1']:.2f} ms" if inf["onnx_ms_batch1"] is not None else "not installed")
              + f"; batch 32: {inf['torch_ms_per_moment_batch32']:.2f} ms a moment")
        tr = training()
        print(f"training (Adadelta, batch {tr['batch']}, forward + backward + clipping): {tr['moments_per_s']:.0f} "
              "moments/s")
        loop = closed_loop(ckpt, args.seconds, Path(tmp))
        stages = ", ".join(f"{k} {v:.2f}" for k, v in loop["stage_ms_per_step"].items() if v)
        print(f"closed loop, MultiNet driving over shared memory (lock-step): {loop['loop_rate_hz']:.0f} Hz "
              f"(ms a step: {stages})")
    if args.json:
        args.json.write_text(json.dumps({"inference": inf, "training": tr, "closed_loop": loop}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
