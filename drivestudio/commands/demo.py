"""drivestudio demo: the whole mission for both worlds at small scale on built-in defaults, every step through the
same verbs a user would run, everything in one folder, ending with REPORT.md (4-10 minutes on a 2-core machine,
by its CPU; --quick: about 3)."""
from __future__ import annotations

import subprocess
import sys
import time
from dataclasses import dataclass, replace
from pathlib import Path

from core.files import make_dir
from drivestudio.cli import main
from drivestudio.commands.demo_report import write_report
from drivestudio.commands.numbers import count
from drivestudio.outputs import write_text


@dataclass(frozen=True)
class Size:
    """How much the demo does: the full demo, or --quick (what the tests run)."""

    warmup: int = 20            # [s] of SUMO traffic before a highway frame
    oracle_seconds: int = 60
    frames: int = 6000          # highway dataset: 100 episodes, the test split (episodes 9, 19, ... 99) 600 frames
    episode_frames: int = 60    # over 1, 2 and 3 lanes; 2,000 frames left the MobileNet behind GIST on 8 of 13
    iterations: int = 1800      # MobileNet (1.9 minutes on a Zen 5 EPYC, 3.4 on a Zen 4)
    overlays: int = 6
    deep_seconds: int = 30
    expert_seconds: int = 20    # each sidewalk expert mode's video
    moments: int = 1800         # sidewalk steps
    sw_episode_frames: int = 150
    epochs: int = 4             # MultiNet and MTL
    autonomy_seconds: int = 60


FULL = Size()
QUICK = Size(warmup=5, oracle_seconds=10, frames=300, episode_frames=10, iterations=10, overlays=3,
             deep_seconds=5, expert_seconds=4, moments=360, sw_episode_frames=40, epochs=1, autonomy_seconds=4)


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the whole pipeline of both worlds at small scale on built-in defaults",
                       description="Highway: frames of three tracks with SUMO traffic; the oracle driving over shared "
                                   "memory (with a video); a small dataset whose test split holds 1, 2 and 3 lanes; "
                                   "the GIST baseline and a MobileNet; their per-indicator MAE as Liu and Wang's "
                                   "Table 3; overlays of the worst frames; the MobileNet driving. Sidewalk: stereo "
                                   "frames; a video of each expert mode; a small data-moment set; a short MultiNet and "
                                   "an MTL net; the autonomy of each in direct mode. Ends with REPORT.md (the two "
                                   "headline tables, every plot and overlay shown where it is discussed, a still of "
                                   "each video beside its link); the commands it ran are in commands.txt.")
    p.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--quick", action="store_true", help="the smallest run that still exercises everything (about "
                                                        "3 minutes; what the tests run)")
    p.add_argument("--frames", type=count(200, 10**6), default=None,
                   help=f"frames in the highway dataset (default {FULL.frames}; quick {QUICK.frames})")
    p.add_argument("--iterations", type=count(1, 10**6), default=None,
                   help=f"MobileNet training iterations (default {FULL.iterations}; quick {QUICK.iterations})")
    p.set_defaults(func=run)


def run(args) -> int:
    size = QUICK if args.quick else FULL
    if args.frames:
        size = replace(size, frames=args.frames)
    if args.iterations:
        size = replace(size, iterations=args.iterations)
    out = make_dir(Path(args.out))
    hw, sw = make_dir(out / "highway"), make_dir(out / "sidewalk")
    step = _Steps()
    stereo = _compile_stereo_kernels()
    try:
        _highway(step, size, hw)
        stereo.wait()
    finally:
        stereo.kill()
    _sidewalk(step, size, sw)
    write_text(out / "commands.txt", "\n".join(step.log) + "\n")
    report = write_report(out, time.perf_counter() - step.t_start, args.quick)
    print(f"\ndemo done in {time.perf_counter() - step.t_start:.0f} s; the report is {report} and everything is in "
          f"{out}/ (the commands it ran: {out / 'commands.txt'})")
    return 0


def _compile_stereo_kernels() -> subprocess.Popen:
    """A child that compiles the stereo renderer's kernels (or loads them from numba's cache) while the highway's
    steps run: in a fresh clone numba compiles them on one thread for about 20 s, and the highway's first frame
    compiles its own on the other core meanwhile. Should it fail, the sidewalk's first frame compiles them itself,
    and says why if that fails too."""
    code = "from sim.sidewalk.kernels import compile_stereo_kernels as c; c()"
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                            cwd=Path(__file__).resolve().parents[2])


class _Steps:
    """Runs the demo's steps through the command's own main(), numbered and timed, and keeps the commands it ran;
    a step that fails ends the demo with its exit status."""

    def __init__(self) -> None:
        self.log: list[str] = []
        self.t_start = time.perf_counter()
        self.done = 0

    def __call__(self, title: str, *argv) -> None:
        self.done += 1
        t0 = time.perf_counter()
        print(f"\n== [{self.done}/{TOTAL}] {title}  ({time.perf_counter() - self.t_start:.0f} s so far)\n"
              f"$ drivestudio {' '.join(map(str, argv))}", flush=True)
        self.log.append("drivestudio " + " ".join(map(str, argv)))
        rc = main([str(a) for a in argv])
        if rc != 0:
            raise SystemExit(rc)
        print(f"({time.perf_counter() - t0:.0f} s)", flush=True)


def _highway(step: _Steps, size: Size, hw: Path) -> None:
    """The highway's steps: frames, the oracle over shared memory, a dataset, the GIST baseline and a MobileNet,
    their Table 3, overlays and the MobileNet driving."""
    data, models = hw / "data", hw / "models"
    for track, lanes in (("oval", 3), ("hairpins", 2), ("sbends", 1)):
        name = f"frame-{track}-{lanes}lane{'s' * (lanes > 1)}"
        step(f"highway: a frame of {track} ({lanes} lane{'s' * (lanes > 1)}) after {size.warmup} s of SUMO traffic",
             "render", "--track", track, "--lanes", lanes, "--cars", 16, "--warmup", size.warmup,
             "-o", hw / f"{name}.png", "--truth", hw / f"{name}.json")
    step(f"highway: the oracle drives {size.oracle_seconds} s, world and driver in two processes over shared memory",
         "drive", "--model", "oracle", "--track", "oval", "--lanes", 3, "--cars", 12, "--seconds",
         size.oracle_seconds, "--record", hw / "oracle-drive.mp4", "--out", hw / "oracle-drive")
    step(f"highway: a labelled dataset ({size.frames} frames, episodes of {size.episode_frames}: every tenth episode "
         "is for testing, and they cycle through 1, 2 and 3 lanes)", "generate", "--out", data, "--frames",
         size.frames, "--episode-frames", size.episode_frames)
    step("highway: what the dataset covers", "stats", data, "--out", hw / "stats")
    step("highway: the GIST baseline", "train", "--data", data, "--model", "gist", "--out", models / "gist.pt")
    step(f"highway: a MobileNet ({size.iterations} iterations of 32 frames; docs/explanation/learned-driving.md)",
         "train", "--data", data, "--model", "mobilenet", "--out", models / "mobilenet.pt", "--iterations",
         size.iterations, "--set", f"val_every={max(5, size.iterations // 3)}", "--set", "val_frames=200",
         "--workers", 0, "--device", "cpu")
    step("highway: per-indicator MAE, as Liu and Wang's Table 3", "evaluate", "--data", data, "--model",
         models / "gist.pt", "--model", models / "mobilenet.pt", "--out", hw / "evaluate", "--latency-frames", 10)
    step("highway: box overlays of the MobileNet's worst test frames", "overlay", "--data", data, "--model",
         models / "mobilenet.pt", "--select", "worst", "-n", size.overlays, "--out", hw / "overlays")
    step(f"highway: the MobileNet drives {size.deep_seconds} s closed loop", "drive", "--model",
         models / "mobilenet.pt", "--track", "oval", "--lanes", 3, "--cars", 12, "--seconds", size.deep_seconds,
         "--record", hw / "mobilenet-drive.mp4", "--out", hw / "mobilenet-drive")


def _sidewalk(step: _Steps, size: Size, sw: Path) -> None:
    """The sidewalk's steps: a stereo pair, the expert modes, a data-moment set, MultiNet and an MTL net, their
    autonomy and the ONNX export."""
    sdata, smodels = sw / "data", sw / "models"
    step("sidewalk: the stereo pair of a park path", "render", "--world", "sidewalk", "--path", "park", "-o",
         sw / "stereo.png", "--truth", sw / "stereo.json")
    for mode in ("direct", "follow", "furtive"):
        step(f"sidewalk: the {mode} expert drives {size.expert_seconds} s over shared memory", "drive", "--world",
             "sidewalk", "--model", "expert", "--mode", mode, "--path", "park", "--seconds", size.expert_seconds,
             "--record", sw / f"expert-{mode}.mp4", "--out", sw / f"expert-{mode}")
    step(f"sidewalk: a data-moment set ({size.moments} steps, the three modes balanced)", "generate", "--world",
         "sidewalk", "--out", sdata, "--frames", size.moments, "--episode-frames", size.sw_episode_frames)
    step("sidewalk: mode balance, steering and motor spread", "stats", sdata, "--out", sw / "stats")
    step(f"sidewalk: MultiNet (Z2Color with the behavioural mode inserted), {size.epochs} epoch(s)", "train",
         "--data", sdata, "--model", "z2color", "--out", smodels / "multinet.pt", "--epochs", size.epochs,
         "--batch-size", 60, "--device", "cpu")
    step(f"sidewalk: the MTL baseline on direct mode's data, {size.epochs} epoch(s)", "train", "--data", sdata,
         "--model", "z2color", "--set", "mtl=direct", "--out", smodels / "mtl-direct.pt", "--epochs", size.epochs,
         "--batch-size", 60, "--device", "cpu")
    for net in ("multinet", "mtl-direct"):
        step(f"sidewalk: autonomy of the {net} net in direct mode, {size.autonomy_seconds} s under the expert's "
             "correction rule", "autonomy", "--model", smodels / f"{net}.pt", "--mode", "direct", "--seconds",
             size.autonomy_seconds, "--out", sw / f"autonomy-{net}")
    step("sidewalk: MultiNet exported to ONNX and checked against PyTorch", "export", "--model",
         smodels / "multinet.pt", "--onnx", smodels / "multinet.onnx")


TOTAL = 11 + 11   # the demo's steps: highway, sidewalk
