"""drivestudio render [SCENARIO.json] -o frame.png: the frame the host car's camera sees."""
from __future__ import annotations

from pathlib import Path

from ..errors import UsageError


def register(sub) -> None:
    p = sub.add_parser("render", help="render the host car's camera frame to a PNG",
                       description="Render the first-person frame of a scenario file, or of a track with SUMO "
                                   "traffic advanced for --warmup simulated seconds.")
    p.add_argument("scenario", nargs="?", help="scenario JSON file (docs/scenarios.md)")
    p.add_argument("-o", "--out", required=True, help="PNG file to write")
    p.add_argument("--truth", help="also write the ground truth of the frame to this JSON file")
    p.add_argument("--track", help="track preset, track file or procedural:SEED (without a scenario)")
    p.add_argument("--lanes", type=int, help="lane count (1-4), overriding the track's")
    p.add_argument("--cars", type=int, default=12, help="AI cars driven by SUMO (without a scenario; default 12)")
    p.add_argument("--warmup", type=float, default=0.0,
                   help="simulated seconds to drive before the frame is taken (without a scenario)")
    p.add_argument("--seed", type=int, default=0, help="seed of the scene's look and of the traffic")
    p.add_argument("--renderer", choices=("tiny", "egl"), default="tiny", help="PyBullet renderer (default tiny)")
    p.add_argument("--width", type=int, default=280, help="frame width in pixels (default 280)")
    p.add_argument("--height", type=int, default=210, help="frame height in pixels (default 210)")
    p.add_argument("--fov", type=float, default=60.0, help="vertical field of view in degrees (default 60)")
    p.set_defaults(func=run)


def run(args) -> int:
    from sim.camera import CameraConfig
    from sim.scenario import load_scenario
    from sim.world import World, WorldConfig

    from ..loop import warm_up
    from ..outputs import write_json, write_png

    if not (16 <= args.width <= 4096 and 16 <= args.height <= 4096):
        raise UsageError("--width and --height must be between 16 and 4096 pixels")
    if not 10 <= args.fov <= 150:
        raise UsageError("--fov must be between 10 and 150 degrees")
    if args.warmup < 0:
        raise UsageError("--warmup must not be negative")
    camera = CameraConfig(width=args.width, height=args.height, fov_deg=args.fov)
    if args.scenario:
        if args.track or args.warmup:
            raise UsageError("--track and --warmup go without a scenario file (a scenario places its own cars)")
        world = World(WorldConfig(renderer=args.renderer, camera=camera, cars=0),
                      scenario=load_scenario(args.scenario, lanes=args.lanes))
    else:
        world = World(WorldConfig(track=args.track or "oval", lanes=args.lanes, cars=args.cars, seed=args.seed,
                                  renderer=args.renderer, camera=camera, render=False, start_speed=15.0))
    with world:
        if args.warmup:
            warm_up(world, args.warmup)
        obs = world.observe(render=True)
        write_png(Path(args.out), obs.frame)
        if args.truth:
            write_json(Path(args.truth), obs.truth.as_dict())
    return 0
