"""The sidewalk world's speed and its experts' safety (issue 12's targets: stereo generation >= 150 steps/s with 2
workers, closed loop over the bridge >= 60 Hz, each expert mode 10 simulated minutes with 0 collisions and 0 s
off the path; issue 48's: the stereo pair drawn >= 3x as fast as on 2026-11-23).

    python bench/bench_stereo.py [--frames 6000] [--seconds 60] [--minutes 10] [--out /tmp/drivestudio-stereo]
                                 [--rounds 5] [--render-only] [--json F]

0. The pair: both images drawn by the compiled kernels and by OpenCV's fills (sim/sidewalk/stereo.py compiled=False,
   the painter before the kernels) from the same poses (every preset and a procedural path, each mode, the expert
   driving), the two in turn round by round; the medians of the rounds' milliseconds a pair, wall-clock and the
   process's CPU time, and of the rounds' ratios (--render-only: this alone).

1. Generation: `drivestudio generate --world sidewalk` (the default paths and modes, 336x188 PNG per camera, two
   images a step), timed end to end (process start-up and every episode's scene set-up included), with 2 and 1
   workers; then where a step's time goes, in one process.
2. Closed loop: `drivestudio drive --world sidewalk --model expert --mode M` (two processes over shared memory,
   lock-step) per mode, from the run's metrics.json.
3. Safety: each mode's expert drives --minutes simulated minutes on a procedural loop with obstacles (in
   process, no frames: the truth is the same); collisions, time off the path, obstacles met.
"""
from __future__ import annotations

import argparse
import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from controller.sidewalk import SidewalkExpert, SidewalkMetrics
from drivestudio import worlds
from perception.shards import encode_image
from sim.sidewalk.paths import preset_names
from sim.sidewalk.stereo import StereoRenderer
from sim.sidewalk.world import SidewalkConfig, SidewalkWorld

MODES = ("direct", "follow", "furtive")


def cpu_model() -> str:
    """The processor's model name, as the kernel lists it."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return "unknown"
    return next((line.split(":", 1)[1].strip() for line in info.splitlines() if line.startswith("model name")),
                "unknown")


def pair_scenes(steps: int = 300, every: int = 10) -> list[tuple]:
    """Per path (the presets and procedural:11) and mode: the world's renderers (compiled, OpenCV's) and the poses
    (x, y, yaw, lead) of its expert's drive, one every `every` steps."""
    out = []
    for i, path in enumerate(preset_names() + ["procedural:11"]):
        for j, mode in enumerate(MODES):
            world = SidewalkWorld(SidewalkConfig(path=path, seed=3 * i + j + 1, mode=mode, render=False))
            expert, obs, poses = SidewalkExpert(), world.observe(False), []
            for k in range(steps):
                obs = world.step(expert.action(obs.record), False)
                if obs.end:
                    world.recover()
                if k % every == every - 1:
                    t = obs.truth
                    poses.append((float(t["x"]), float(t["y"]), float(t["yaw"]),
                                  world.lead.state if world.lead else None))
            renderers = {compiled: StereoRenderer(world.layout, world.seed, world.config.stereo, compiled=compiled)
                         for compiled in (True, False)}
            out.append((renderers, poses))
    return out


def render_pair(rounds: int) -> dict:
    """Milliseconds a stereo pair (wall-clock and CPU), compiled and OpenCV's, medians of alternating rounds."""
    scenes = pair_scenes()
    for renderers, poses in scenes:   # numba's cache loaded, the first pair's allocations made
        for r in renderers.values():
            r.render(*poses[0][:3], poses[0][3])
    pairs = sum(len(poses) for _, poses in scenes)
    times: dict = {name: {"wall": [], "cpu": []} for name in ("numba", "opencv")}
    for k in range(rounds):
        for compiled in ((True, False) if k % 2 == 0 else (False, True)):
            t, c = time.perf_counter(), time.process_time()
            for renderers, poses in scenes:
                for x, y, yaw, lead in poses:
                    renderers[compiled].render(x, y, yaw, lead)
            name = "numba" if compiled else "opencv"
            times[name]["wall"].append((time.perf_counter() - t) / pairs * 1e3)
            times[name]["cpu"].append((time.process_time() - c) / pairs * 1e3)
    out = {"cpu": cpu_model(), "pairs_a_round": pairs, "rounds": rounds,
           **{f"{name}_{kind}_ms": statistics.median(v) for name, d in times.items() for kind, v in d.items()}}
    for kind in ("wall", "cpu"):
        out[f"ratio_{kind}"] = statistics.median(o / n for o, n in zip(times["opencv"][kind], times["numba"][kind]))
        out[f"ratio_{kind}_rounds"] = [round(o / n, 2) for o, n in zip(times["opencv"][kind], times["numba"][kind])]
    return out


def generate(out: Path, frames: int, workers: int) -> float:
    shutil.rmtree(out, ignore_errors=True)
    t0 = time.perf_counter()
    subprocess.run([sys.executable, "-m", "drivestudio", "generate", "--world", "sidewalk", "--out", str(out),
                    "--frames", str(frames), "--workers", str(workers)], check=True)
    return frames / (time.perf_counter() - t0)


def breakdown(steps: int = 600) -> dict:
    """CPU milliseconds per step of one process recording an episode: render (both cameras), PNG (both), the
    world's step (physics, lead car, truth), the expert, and the scene's set-up spread over the steps."""
    plugin = worlds.get("sidewalk")
    options = {"modes": list(MODES), "paths": [], "procedural": 3, "obstacles": 4.0, "correctional": 0.0,
               "width": 336, "height": 188, "fov": 56.0}
    total = {"set-up": 0.0, "render": 0.0, "png": 0.0, "world": 0.0, "expert": 0.0}
    n = 0
    for ep in plugin.plan(options, 3 * steps, steps, 0):
        t = time.process_time()
        world, expert, _ = plugin.episode(ep, options, "tiny")
        assert isinstance(world, SidewalkWorld)   # the sidewalk plugin's world: its renderer is timed apart
        obs = world.observe(True)
        total["set-up"] += time.process_time() - t
        for _ in range(ep.frames):
            t0 = time.process_time()
            frames = obs.frames
            for img in frames:
                encode_image(img)
            t1 = time.process_time()
            action, _ = expert.act(obs)
            t2 = time.process_time()
            obs = world.step(action, False)
            t3 = time.process_time()
            x, y, yaw = (float(obs.record[world.declaration.index(k)]) for k in ("x", "y", "yaw"))
            frames = world.renderer.render(x, y, yaw, world.lead.state if world.lead else None)
            obs.frames = frames
            t4 = time.process_time()
            total["png"] += t1 - t0
            total["expert"] += t2 - t1
            total["world"] += t3 - t2
            total["render"] += t4 - t3
            n += 1
    return {k: v / n * 1e3 for k, v in total.items()}


def closed_loop(mode: str, seconds: float) -> dict:
    with tempfile.TemporaryDirectory() as tmp:
        subprocess.run([sys.executable, "-m", "drivestudio", "drive", "--world", "sidewalk", "--model", "expert",
                        "--mode", mode, "--seconds", str(seconds), "--out", tmp], check=True,
                       stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        return json.loads((Path(tmp) / "metrics.json").read_text())


def safety(mode: str, minutes: float, path: str = "procedural:11", seed: int = 5) -> dict:
    world = SidewalkWorld(SidewalkConfig(path=path, seed=seed, mode=mode, obstacles=5.0, render=False))
    expert, metrics = SidewalkExpert(), SidewalkMetrics(world.dt)
    obs = world.observe(False)
    t0 = time.perf_counter()
    for _ in range(int(round(minutes * 60 / world.dt))):
        obs = world.step(expert.action(obs.record), False)
        metrics.update(obs.record)
    metrics.wall_time = time.perf_counter() - t0
    return metrics.report()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=6000, help="steps generated with 2 workers (half with 1)")
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds of each closed-loop run")
    ap.add_argument("--minutes", type=float, default=10.0, help="simulated minutes of each safety run")
    ap.add_argument("--out", default="/tmp/drivestudio-stereo")
    ap.add_argument("--rounds", type=int, default=5, help="rounds of the pair's render figure")
    ap.add_argument("--render-only", action="store_true", help="the pair's render figure alone")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args()
    figures = {"frames": args.frames, "seconds": args.seconds, "minutes": args.minutes, "closed_loop": {},
               "safety": {}}
    p = figures["render_pair"] = render_pair(args.rounds)
    print(f"stereo pair drawn, 2 x 336x188, one process, {p['pairs_a_round']} pairs a round, median of {p['rounds']} "
          f"rounds: compiled {p['numba_wall_ms']:.2f} ms a pair ({p['numba_cpu_ms']:.2f} CPU), OpenCV's fills "
          f"{p['opencv_wall_ms']:.2f} ms ({p['opencv_cpu_ms']:.2f} CPU): {p['ratio_wall']:.2f}x ({p['ratio_cpu']:.2f}x "
          f"CPU; rounds {p['ratio_wall_rounds']}); {p['cpu']}", flush=True)
    if args.render_only:
        if args.json:
            args.json.write_text(json.dumps(figures, indent=2, default=str) + "\n")
        return
    out = Path(args.out)
    two = generate(out / "w2", args.frames, 2)
    one = generate(out / "w1", args.frames // 2, 1)
    print(f"stereo generation, 336x188 x 2 cameras, PNG: {two:.0f} steps/s with 2 workers, {one:.0f} steps/s with "
          f"1 worker (end to end)", flush=True)
    figures.update(generation_2_workers_steps_per_s=two, generation_1_worker_steps_per_s=one)
    b = breakdown()
    figures["breakdown_ms_per_step"] = b
    print("one process, CPU ms per step: " + ", ".join(f"{k} {v:.2f}" for k, v in b.items())
          + f"; total {sum(b.values()):.2f}", flush=True)
    print("\n| mode | loop Hz | render ms | transfer ms | control ms | physics + truth ms |")
    print("|---|---|---|---|---|---|")
    for mode in MODES:
        m = closed_loop(mode, args.seconds)
        st = m["stage_ms_per_step"]
        figures["closed_loop"][mode] = {"loop_hz": m["loop_rate_hz"], "stage_ms_per_step": st}
        print(f"| {mode} | {m['loop_rate_hz']:.0f} | {st['render']:.2f} | {st['transfer']:.2f} | "
              f"{st['control']:.3f} | {st['physics'] + st['truth']:.2f} |", flush=True)
    print(f"\n| mode, {args.minutes:g} min on procedural:11 | distance m | mean speed m/s | collisions | "
          "off path s | obstacles met | lead gap m (sd) | border m |")
    print("|---|---|---|---|---|---|---|---|")
    for mode in MODES:
        r = safety(mode, args.minutes)
        figures["safety"][mode] = r
        lead = f"{r['mean_lead_gap_m']} ({r['lead_gap_std_m']})" if r["mean_lead_gap_m"] is not None else "-"
        print(f"| {mode} | {r['distance_m']:.0f} | {r['mean_speed_mps']:.2f} | {r['collisions']} | "
              f"{r['off_path_time_s']} | {r['obstacles_met']} | {lead} | {r['mean_border_distance_m'] or '-'} |",
              flush=True)
    if args.json:
        args.json.write_text(json.dumps(figures, indent=2, default=str) + "\n")


if __name__ == "__main__":
    main()
