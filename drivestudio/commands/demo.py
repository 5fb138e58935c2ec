"""drivestudio demo: the whole mission at small scale on built-in defaults, every step through the same verbs a
user would run, everything in one folder (about five minutes on a 2-core laptop)."""
from __future__ import annotations

import time
from pathlib import Path

from ..numbers import count


def register(sub) -> None:
    p = sub.add_parser("demo", help="run the whole pipeline at small scale on built-in defaults",
                       description="Render frames of three tracks with SUMO traffic; drive closed loop with the "
                                   "oracle over shared memory (with a video); generate a small dataset and inspect "
                                   "it; train the GIST baseline and a short AlexNet; evaluate both as the paper's "
                                   "Table 3; draw overlays of the worst frames; drive closed loop with the AlexNet. "
                                   "Results land in --out; the commands it ran are listed in commands.txt.")
    p.add_argument("--out", default="out/demo", help="output folder (default out/demo)")
    p.add_argument("--frames", type=count(200, 10**6), default=2000, help="frames in the demo dataset (default 2000)")
    p.add_argument("--iterations", type=count(1, 10**6), default=150, help="AlexNet training iterations (default 150)")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..cli import main
    from ..outputs import write_text

    from perception.files import make_dir
    out = make_dir(Path(args.out))
    data, ckpt = out / "data", out / "models"
    log: list[str] = []
    t_start = time.perf_counter()

    def step(title: str, *argv) -> None:
        t0 = time.perf_counter()
        print(f"\n== {title}\n$ drivestudio {' '.join(map(str, argv))}", flush=True)
        log.append("drivestudio " + " ".join(map(str, argv)))
        rc = main([str(a) for a in argv])
        if rc != 0:
            raise SystemExit(rc)
        print(f"({time.perf_counter() - t0:.0f} s)", flush=True)

    for track, lanes in (("oval", 3), ("hairpins", 2), ("sbends", 1)):
        name = f"frame-{track}-{lanes}lane{'s' * (lanes > 1)}"
        step(f"a frame of {track} ({lanes} lane{'s' * (lanes > 1)}) after 20 s of SUMO traffic", "render",
             "--track", track, "--lanes", lanes, "--cars", 16, "--warmup", 20, "-o", out / f"{name}.png",
             "--truth", out / f"{name}.json")
    step("the oracle drives 60 s closed loop, world and driver in two processes over shared memory", "drive",
         "--model", "oracle", "--track", "oval", "--lanes", 3, "--cars", 12, "--seconds", 60,
         "--record", out / "oracle-drive.mp4", "--out", out / "oracle-drive")
    step("a labelled dataset (episodes of 200 frames: 8 for training, 1 for validation, 1 for testing)",
         "generate", "--out", data, "--frames", args.frames, "--episode-frames", 200, "--quiet")
    step("what the dataset covers", "stats", data, "--out", out / "stats")
    step("the GIST baseline", "train", "--data", data, "--model", "gist", "--out", ckpt / "gist.pt")
    step("a short AlexNet (the paper trains 10,000 iterations; see docs/results.md)", "train", "--data", data,
         "--model", "alexnet", "--out", ckpt / "alexnet.pt", "--iterations", args.iterations, "--optimizer", "adam",
         "--lr", "1e-4", "--val-every", max(50, args.iterations // 3), "--val-frames", 200)
    step("per-indicator MAE, as the paper's Table 3", "evaluate", "--data", data, "--model", ckpt / "gist.pt",
         "--model", ckpt / "alexnet.pt", "--out", out / "evaluate", "--latency-frames", 20)
    step("box overlays of the AlexNet's worst test frames", "overlay", "--data", data, "--model",
         ckpt / "alexnet.pt", "--select", "worst", "-n", 6, "--out", out / "overlays")
    step("the AlexNet drives 30 s closed loop", "drive", "--model", ckpt / "alexnet.pt", "--track", "oval",
         "--lanes", 3, "--cars", 12, "--seconds", 30, "--record", out / "alexnet-drive.mp4",
         "--out", out / "alexnet-drive")
    write_text(out / "commands.txt", "\n".join(log) + "\n")
    print(f"\ndemo done in {time.perf_counter() - t_start:.0f} s; everything is in {out}/ "
          f"(the commands it ran: {out / 'commands.txt'})")
    return 0
