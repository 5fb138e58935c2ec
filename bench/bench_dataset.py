"""Dataset generation frames/s (1 and 2 workers) and training-loader frames/s (issue 5's targets: 200 and 2000).

    python bench/bench_dataset.py [--frames 4000] [--out /tmp/drivestudio-bench] [--json F]

Generation: the default mix of tracks, lanes and traffic, 280x210 PNG, timed end to end (process start-up,
SUMO and scene set-up of every episode included). Reading: FrameStream through a DataLoader (decode + tensor,
the way training reads) and FrameDataset random access.
"""
from __future__ import annotations

import argparse
import json
import shutil
import subprocess
import sys
import time
from pathlib import Path

import torch

from perception.datasets import FrameDataset, FrameStream


def gen(out: Path, frames: int, workers: int) -> float:
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "drivestudio", "generate", "--out", str(out), "--frames", str(frames),
                    "--workers", str(workers)], check=True)
    return frames / (time.perf_counter() - t0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=4000)
    ap.add_argument("--out", default="/tmp/drivestudio-bench")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    figures = {"frames": args.frames}
    out = Path(args.out)
    one = gen(out / "w1", args.frames // 2, 1)
    two = gen(out / "w2", args.frames, 2)
    print(f"generation: {two:.0f} frames/s with 2 workers, {one:.0f} frames/s with 1 worker "
          f"(484,815 frames with 2 workers: {484815 / two / 60:.0f} min)")
    figures.update(generation_2_workers_frames_per_s=two, generation_1_worker_frames_per_s=one)
    data = out / "w2"
    for workers in (0, 1, 2):
        loader = torch.utils.data.DataLoader(FrameStream(data, split="all"), batch_size=64, num_workers=workers)
        t0 = time.perf_counter()
        n = sum(len(batch[0]) for batch in loader)
        rate = n / (time.perf_counter() - t0)
        figures[f"stream_{workers}_workers_frames_per_s"] = rate
        print(f"reading, stream, {workers} loader workers: {rate:.0f} frames/s")
    ds = FrameDataset(data, split="all")
    idx = torch.randperm(len(ds))[:1000].tolist()
    t0 = time.perf_counter()
    for i in idx:
        ds[i]
    rate = len(idx) / (time.perf_counter() - t0)
    figures["random_access_frames_per_s"] = rate
    print(f"reading, random access, 1 process: {rate:.0f} frames/s")
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2) + "\n")


if __name__ == "__main__":
    main()
