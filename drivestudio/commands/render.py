"""drivestudio render [SCENARIO.json] -o frame.png: the frame (or frames, one per camera) the host car sees."""
from __future__ import annotations

from pathlib import Path

from core.files import check_output
from drivestudio.commands.common import add_world_options, plugin_for, world_config
from drivestudio.commands.numbers import non_negative
from drivestudio.errors import UsageError
from drivestudio.outputs import write_json, write_png


def register(sub) -> None:
    p = sub.add_parser("render", help="render the host car's camera frame(s) to PNG",
                       description="Render the first-person frame of a world: for the highway, of a scenario file or "
                                   "of a track with SUMO traffic advanced for --warmup simulated seconds; a world with "
                                   "several cameras writes one PNG per camera (NAME-left.png, NAME-right.png).")
    p.add_argument("scenario", nargs="?", help="highway scenario JSON file (docs/scenarios.md)")
    p.add_argument("-o", "--out", required=True, help="PNG file to write")
    p.add_argument("--truth", help="also write the ground truth of the frame to this JSON file")
    p.add_argument("--warmup", type=non_negative(3600.0), default=0.0,
                   help="simulated seconds the world's own driver drives before the frame is taken (default 0)")
    add_world_options(p, "render")
    p.set_defaults(func=run)


def camera_paths(out: Path, cameras) -> dict:
    """One path per camera: OUT itself for one camera, OUT-CAMERA.png for several."""
    if len(cameras) == 1:
        return {cameras[0]: out}
    return {c: out.with_name(f"{out.stem}-{c}{out.suffix}") for c in cameras}


def run(args) -> int:
    plugin = plugin_for(args)
    out = check_output(args.out, (".png",), "frame")
    if args.truth:
        check_output(args.truth, (".json",), "truth file")
    if args.scenario and args.world != "highway":
        raise UsageError("a scenario file describes a highway scene (--world highway)")
    if args.scenario and (args.track or args.warmup):
        raise UsageError("--track and --warmup go without a scenario file (a scenario places its own cars)")
    frames, truth = plugin.render(world_config(plugin, args), args.warmup, args.scenario)
    paths = camera_paths(out, list(frames))
    for path in paths.values():
        check_output(path, (".png",), "frame")
    for cam, image in frames.items():
        write_png(paths[cam], image)
    if args.truth:
        write_json(Path(args.truth), truth)
    if len(paths) > 1:
        print("wrote " + ", ".join(str(p) for p in paths.values()))
    return 0
