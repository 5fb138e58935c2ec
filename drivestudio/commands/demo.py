"""drivestudio demo: the main job on built-in defaults, small enough for a laptop, written to one folder."""
from __future__ import annotations

import time
from pathlib import Path


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the whole pipeline on built-in defaults (a few minutes on a laptop)",
                       description="Render frames of several tracks with SUMO traffic, then drive closed loop "
                                   "with the oracle; everything lands in --out.")
    p.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--seconds", type=float, default=120.0, help="simulated seconds of closed-loop driving")
    p.set_defaults(func=run)


def run(args) -> int:
    from controller.metrics import ClosedLoopMetrics
    from sim.world import World, WorldConfig

    from ..loop import Driver, in_process, run_loop, warm_up
    from ..outputs import write_json, write_png, write_text

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    t0 = time.perf_counter()
    for track, lanes in (("oval", 3), ("hairpins", 2), ("sbends", 1)):
        with World(WorldConfig(track=track, lanes=lanes, cars=12, seed=1, render=False, start_speed=15.0)) as w:
            warm_up(w, 30.0)
            obs = w.observe(render=True)
            write_png(out / f"frame-{track}-{lanes}lane.png", obs.frame)
            write_json(out / f"frame-{track}-{lanes}lane.json", obs.truth.as_dict())
        print(f"rendered {track} ({lanes} lanes) after 30 s of traffic", flush=True)
    with World(WorldConfig(track="oval", lanes=3, cars=12, seed=2, render=False, start_speed=15.0)) as w:
        metrics = ClosedLoopMetrics(w.track.length, w.config.dt)
        run_loop(w, in_process(Driver()), args.seconds, render=False, metrics=metrics)
    write_json(out / "oracle-drive.json", metrics.report())
    write_text(out / "oracle-drive.md", metrics.table() + "\n")
    print(metrics.table())
    print(f"demo done in {time.perf_counter() - t0:.0f} s; results in {out}/")
    return 0
