"""Draw docs/img/benchmark-oracles.png: the plain oracle's crash on a benchmark route beside the extended oracle
driving the same seconds of the same route, as crash-clip frames (the box overlay over the controller panel).

    .venv/bin/python docs/figures/oracle_stills.py --suite assets/suites/controller-hard.json --route p4-2l-s134 \\
        --event 135.4 --out docs/img/benchmark-oracles.png

Both models drive the route from its start exactly as `drivestudio benchmark` drives it (the same world, seed and
driver); the frames at the given offsets from the event are kept, scaled down and laid out in two rows.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from drivestudio.loop import in_process, run_loop  # noqa: E402
from drivestudio.worlds.highway.benchmark import RunOptions, check_models, load_suite  # noqa: E402
from drivestudio.worlds.highway.benchmark.clips import ClipRecorder, rule_at_fault  # noqa: E402
from drivestudio.worlds.highway.benchmark.route import driver_for, world_for  # noqa: E402


def frames_of(route, model, event: float, offsets: list[float]) -> list[np.ndarray]:
    """The clip frames of `model` on `route` at event + offset [s] for each offset."""
    world = world_for(route)
    recorder = ClipRecorder(world, route, model, None, RunOptions(clips=0))
    wanted = {int(round((event + o) / world.dt)): o for o in offsets}
    kept: dict[float, object] = {}
    history: list = []

    def on_step(rec) -> None:
        recorder(rec)
        entry = recorder.buffer[-1]
        history.append(entry)
        step = int(round(rec.obs.t / world.dt))
        if step in wanted:
            kept[wanted[step]] = entry
    try:
        run_loop(world, in_process(driver_for(model, "cpu")), event + max(offsets) + 2 * world.dt, render=True,
                 on_step=on_step)
        at_event = [e for e in history if e.obs.t <= event + 1e-6][-int(round(5.0 / world.dt)):]
        crashed = bool(at_event[-1].obs.collision)
        info = {"event": "collision" if crashed else "no collision: the oracle's collision time", "t": event,
                "largest_error": None, "contact": "-" if not crashed else "see the oracle's clip",
                "rule": rule_at_fault(at_event, world.dt) if crashed else ""}
        return [recorder.frame(kept[o], event, info, mark=crashed) for o in offsets]
    finally:
        world.close()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--suite", required=True)
    ap.add_argument("--route", required=True)
    ap.add_argument("--event", type=float, required=True, help="the oracle's collision time [s]")
    ap.add_argument("--offsets", default="-2,-1,0", help="seconds from the event of the frames kept")
    ap.add_argument("--scale", type=float, default=0.55)
    ap.add_argument("--out", required=True)
    args = ap.parse_args()
    route = load_suite(args.suite).select([args.route]).routes[0]
    offsets = [float(x) for x in args.offsets.split(",")]
    rows = []
    for model in check_models(["oracle-extended"]):
        frames = frames_of(route, model, args.event, offsets)
        rows.append(np.hstack([cv2.resize(f, None, fx=args.scale, fy=args.scale, interpolation=cv2.INTER_AREA)
                               for f in frames]))
    image = np.vstack(rows)
    cv2.imwrite(args.out, cv2.cvtColor(image, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_PNG_COMPRESSION, 9])
    print(f"wrote {args.out} ({Path(args.out).stat().st_size // 1024} kB, {image.shape[1]}x{image.shape[0]})")


if __name__ == "__main__":
    main()
