"""MultiNet's speed (targets: Z2Color inference <= 5 ms per data moment at batch 1 on this CPU, closed loop over the
bridge >= 30 Hz, training >= 250 moments/s).

    python bench/bench_multinet.py [--repeats 200] [--seconds 20] [--json F]

1. Inference: a Z2Color MultiNet on one data moment (four 336x188 images, averaged to 12 x 94 x 168 inside the
   model) at batch 1, in PyTorch (inference mode) and through its ONNX export in ONNX Runtime; also batch 32.
2. Training: moments per second of MultiNet's training (Adadelta, batch 120, gradient clipping, balanced modes) on
   real moments of a small generated data set, cached at 94 x 168 as the trainer caches them: the trainer as it
   is and as it was (float32, default layout), alternately; then two one-thread trainings side by side, each its
   own process (the study's setting), and the time to assemble one batch through the pixel table and as before.
3. Closed loop: `drivestudio drive --world sidewalk --model CKPT` with the network as a driver process over shared
   memory, lock-step at the world's 30 Hz simulated rate, run as fast as it can; the loop rate from metrics.json.
"""
from __future__ import annotations

import argparse
import json
import os
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
    out: dict[str, float | None] = {"threads": torch.get_num_threads(),
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


def dataset(folder: Path) -> Path:
    """A small real sidewalk data set (every mode), its moments cached at 94 x 168 by the trainer's cache."""
    out = folder / "data"
    subprocess.run([sys.executable, "-m", "drivestudio", "generate", "--world", "sidewalk", "--out", str(out),
                    "--frames", "240", "--episode-frames", "40", "--paths", "park"], check=True,
                   capture_output=True)
    return out


def training(data: Path, batches: int = 12, batch: int = 120, rounds: int = 3) -> dict:
    """Moments/s of MultiNet's training on real cached moments (Adadelta, gradient clipping, balanced batches),
    the trainer as it was (float32 weights and images in the default layout, the batch assembled and scaled
    between steps) and as it is (perception/multinet.py's train_epoch: channels-last, bfloat16 autocast where the CPU
    computes it natively, the next batch assembled in a second thread), alternately, `rounds` times each; the
    medians."""
    import torch

    from perception.multinet import CLIP, balanced_batches, new_network, resolve, train_epoch, train_loss
    from perception.training import config_from
    cfg = config_from(data=str(data), model="z2color", out=str(data.parent / "bench.pt"), epochs=1, batch_size=batch,
                      device="cpu")
    run = resolve(cfg, log=lambda *a: None)
    run.train_ids = {m: np.resize(ids, batches * batch // 3) for m, ids in run.train_ids.items()}   # `batches` steps

    def before() -> tuple[float, float]:
        model, opt = new_network(run, 0)
        model = model.to(memory_format=torch.contiguous_format)
        t0, c0, n = time.perf_counter(), time.process_time(), 0
        for ids in balanced_batches(run.train_ids, batch, np.random.default_rng(0), run.steps):
            x, m, y = run.moments.batch(ids)
            x = x.contiguous()
            target = torch.from_numpy(run.moments.decl.normalise(y.numpy(), model.outputs))
            loss = train_loss(model(x, m), target)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(model.parameters(), CLIP)
            opt.step()
            n += len(ids)
        return n / (time.perf_counter() - t0), n / (time.process_time() - c0)

    def now() -> tuple[float, float]:
        model, opt = new_network(run, 0)
        t0, c0 = time.perf_counter(), time.process_time()
        n = run.steps * batch
        train_epoch(run, model, opt, 0, 1)
        return n / (time.perf_counter() - t0), n / (time.process_time() - c0)

    before(), now()                                      # warm-up: oneDNN picks its kernels
    pairs = [(before(), now()) for _ in range(rounds)]

    def median(k: int, j: int) -> float:
        return round(float(np.median([p[k][j] for p in pairs])), 1)
    cores = torch.get_num_threads()
    return {"before_moments_per_s": median(0, 0), "moments_per_s": median(1, 0),
            # moments per second of CPU time, times the threads: what the cores would give if nothing else ran
            "before_per_cpu_s": median(0, 1), "per_cpu_s": median(1, 1), "threads": cores,
            "rounds": [[round(a[0], 1), round(b[0], 1)] for a, b in pairs], "batch": batch, "amp": run.amp}


def one_trainer(data: Path, batches: int = 24, batch: int = 120) -> dict:
    """This process's training rate (moments/s of train_epoch after a warm-up epoch) and the time the trainer's
    second thread takes to assemble one batch (inputs(): cached pixels through the network's table) against the
    way it was assembled before the table (moments.batch, scale_input, the cast): medians of `batches`."""
    import torch

    from perception.multinet import inputs, new_network, resolve, train_epoch
    from perception.training import config_from
    cfg = config_from(data=str(data), model="z2color", out=str(data.parent / "bench.pt"), epochs=1, batch_size=batch,
                      device="cpu")
    run = resolve(cfg, log=lambda *a: None)
    run.train_ids = {m: np.resize(ids, batches * batch // 3) for m, ids in run.train_ids.items()}
    model, opt = new_network(run, 0)
    train_epoch(run, model, opt, 0, 1)                                        # warm-up: oneDNN picks its kernels
    rate = train_epoch(run, model, opt, 0, 2)["moments_per_s"]
    ids = np.concatenate(list(run.train_ids.values()))[:batch]
    dtype = torch.bfloat16 if run.amp else torch.float32

    def before():
        x, _, _ = run.moments.batch(ids)
        return model.scale_input(x).to(dtype)
    return {"moments_per_s": rate, "assembly_ms": _median_ms(lambda: inputs(run, model, ids), batches),
            "assembly_before_ms": _median_ms(before, batches)}


def side_by_side(data: Path) -> dict:
    """Two one-thread trainings at once, each its own process (the study's setting: `--jobs 2` on two cores): the
    mean of their rates, and the batch assembly times of the first."""
    env = os.environ | {"OMP_NUM_THREADS": "1"}
    procs = [subprocess.Popen([sys.executable, __file__, "--one-trainer", str(data)], env=env, stdout=subprocess.PIPE,
                              text=True) for _ in range(2)]
    got = [json.loads(p.communicate()[0].strip().splitlines()[-1]) for p in procs]
    if any(p.returncode for p in procs):
        raise RuntimeError("a side-by-side trainer failed")
    return {"moments_per_s_each": round(float(np.mean([g["moments_per_s"] for g in got])), 1),
            "assembly_ms": round(got[0]["assembly_ms"], 1),
            "assembly_before_ms": round(got[0]["assembly_before_ms"], 1)}


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
    ap.add_argument("--one-trainer", type=Path, help=argparse.SUPPRESS)   # side_by_side's worker: a data folder
    args = ap.parse_args(argv)
    if args.one_trainer:
        print(json.dumps(one_trainer(args.one_trainer)))
        return 0
    with tempfile.TemporaryDirectory(prefix="bench-multinet-") as tmp:
        ckpt = checkpoint(Path(tmp))
        inf = inference(ckpt, args.repeats)
        print(f"Z2Color MultiNet inference, one data moment (4 x 336x188 images), batch 1, {inf['threads']} threads: "
              f"PyTorch {inf['torch_ms_batch1']:.2f} ms, ONNX Runtime "
              + (f"{inf['onnx_ms_batch1']:.2f} ms" if inf["onnx_ms_batch1"] is not None else "not installed")
              + f"; batch 32: {inf['torch_ms_per_moment_batch32']:.2f} ms a moment")
        data = dataset(Path(tmp))
        tr = training(data)
        print(f"training on real cached moments (Adadelta, batch {tr['batch']}, balanced modes, clipping): "
              f"{tr['moments_per_s']:.0f} moments/s (channels-last, "
              f"{'bfloat16 autocast' if tr['amp'] else 'float32: bfloat16 is not native here'}, batches prefetched), "
              f"{tr['before_moments_per_s']:.0f} as before (float32, default layout); alternate rounds "
              f"{tr['rounds']}; per second of CPU time {tr['per_cpu_s']:.0f} and {tr['before_per_cpu_s']:.0f} "
              f"({tr['threads']} threads)")
        tr["side_by_side"] = sbs = side_by_side(data)
        print(f"two one-thread trainings side by side (the study's setting): {sbs['moments_per_s_each']:.0f} "
              f"moments/s each; a batch assembled in {sbs['assembly_ms']:.0f} ms (through the pixel table; "
              f"{sbs['assembly_before_ms']:.0f} ms as before it)")
        loop = closed_loop(ckpt, args.seconds, Path(tmp))
        stages = ", ".join(f"{k} {v:.2f}" for k, v in loop["stage_ms_per_step"].items() if v)
        print(f"closed loop, MultiNet driving over shared memory (lock-step): {loop['loop_rate_hz']:.0f} Hz "
              f"(ms a step: {stages})")
    if args.json:
        args.json.write_text(json.dumps({"inference": inf, "training": tr, "closed_loop": loop}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
