"""Training samples/s and inference frames/s of each perception model on this machine, at 210x280.

Models: AlexNet (from scratch), VGG-16 with the convolutional layers frozen, VGG-16 with everything trained,
GIST + ridge. Training is one SGD step per batch at the paper's batch sizes (15 AlexNet, 10 VGG-16); GIST has
no gradient step, so its "training" figure is descriptors computed per second (its fit is one closed-form
solve on top). Inference is batched (32) and single-frame (latency, the closed loop's case). Random frames:
the cost does not depend on the content.

    python bench/bench_perception.py [--device cpu|cuda] [--steps 5] [--models alexnet,vgg16,vgg16-unfrozen,gist]
                                     [--json F]
"""
from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import torch

from core import worlds
from core.worlds.highway import label_set
from perception.models import build, family
from perception.training import euclidean_loss

H, W = 210, 280
MODELS = {"alexnet": ("alexnet", {}), "vgg16": ("vgg16", {"frozen": True}),
          "vgg16-unfrozen": ("vgg16", {"frozen": False}), "gist": ("gist", {})}


def _sync(device):
    if device.type == "cuda":
        torch.cuda.synchronize()


def timed(fn, steps: int, device, warmup: int = 1) -> float:
    """Median seconds of `fn()` over `steps` runs after `warmup` untimed ones."""
    for _ in range(warmup):
        fn()
    times = []
    for _ in range(steps):
        _sync(device)
        t0 = time.perf_counter()
        fn()
        _sync(device)
        times.append(time.perf_counter() - t0)
    return sorted(times)[len(times) // 2]


def training_step(model, name: str, x: torch.Tensor, y: torch.Tensor):
    """One training step of `model` on (x, y) as a function: GIST computes descriptors (its fit is closed-form),
    the others take an SGD step."""
    if name == "gist":
        model.eval()

        def describe() -> None:
            with torch.no_grad():
                model.net.descriptor(x.float() / 255)
        return describe
    model.train()
    opt = torch.optim.SGD([p for p in model.parameters() if p.requires_grad], lr=1e-6, momentum=0.9)

    def step() -> None:
        loss = euclidean_loss(model(x), y)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        opt.step()
    return step


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--steps", type=int, default=5, help="timed repetitions per figure (median reported)")
    ap.add_argument("--models", default=",".join(MODELS))
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    rows = []
    device = torch.device(args.device)
    labels = label_set()
    what = torch.cuda.get_device_name() if device.type == "cuda" else \
        f"{platform.machine()} CPU, {torch.get_num_threads()} threads"
    print(f"perception benchmark at {W}x{H}, {len(labels)} outputs, on {what} (torch {torch.__version__})")
    print(f"{'model':16s} {'train samples/s':>16s} {'batch':>6s} {'infer frames/s (32)':>20s} {'latency ms (1)':>15s}")
    g = torch.Generator().manual_seed(0)
    for key in args.models.split(","):
        name, options = MODELS[key]
        model = build(name, worlds.get("highway"), labels, **options).to(device)
        batch = family(name).defaults["batch_size"] if name != "gist" else 32
        x = torch.randint(0, 256, (batch, 3, H, W), dtype=torch.uint8, generator=g).to(device)
        y = torch.rand(batch, len(labels), generator=g).to(device)
        train_rate = batch / timed(training_step(model, name, x, y), args.steps, device)
        model.eval()
        xb = torch.randint(0, 256, (32, 3, H, W), dtype=torch.uint8, generator=g).to(device)
        with torch.inference_mode():
            infer_rate = 32 / timed(lambda model=model, xb=xb: model(xb), max(2, args.steps // 2), device)
            latency = timed(lambda model=model, xb=xb: model(xb[:1]), args.steps * 4, device, warmup=3)
        print(f"{key:16s} {train_rate:16.1f} {batch:6d} {infer_rate:20.1f} {latency * 1e3:15.1f}", flush=True)
        rows.append({"model": key, "train_samples_per_s": train_rate, "batch": batch,
                     "infer_frames_per_s": infer_rate, "latency_ms": latency * 1e3})
        del model  # free this model before the next is built
    if args.json:
        args.json.write_text(json.dumps({"device": str(device), "on": what, "steps": args.steps, "models": rows},
                                        indent=2) + "\n")


if __name__ == "__main__":
    main()
