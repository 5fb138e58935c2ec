"""drivestudio's Highway-v0 against highway-env's highway-v0, side by side, alternating in the same run.

Ours: `gymnasium.make("drivestudio/Highway-v0", track="oval", lanes=3, cars=12)` driven by the Chen controller on
the true indicators of `info`, a 280x210 camera frame every step (3-D, PyBullet, SUMO traffic, exact ground
truth). Theirs: highway-env 1.12.1 `highway-v0` with lanes_count 3, vehicles_count 12, a 280x210 `rgb_array`
render after every step (its 2-D top-down view), the IDLE action. The two run in turn, `--steps` steps each, for
`--rounds` rounds, so that both see the same machine load; each side's steps/s is the median over the rounds,
with resets (a new episode) timed apart and left out. The ratio is ours over theirs.

A step is not the same thing on both sides: ours is 0.1 simulated s with one frame; highway-v0's is 1 / policy_
frequency = 1 s of 15 simulation frames, and once render() has been called highway-env draws every one of them
(its "automatic rendering"), then returns the last. So the bench also reports each side's simulated seconds per
wall second (x real time), which is the fairer figure of simulation speed; steps/s is the figure of an agent's
decisions per second, each with a fresh 280x210 frame, which is what the issue compares.

highway-env is not a dependency of drivestudio: it is installed on first use into its own virtual environment
(`.venv-highway-env/` in the repository, `pip install highway-env==1.12.1`) and runs in a subprocess
(bench/_highway_env_worker.py) that reports its timings as JSON. Without it (offline, no pip) the bench says so
in one line and records the comparison as not measured.

    python bench/bench_highway_env.py [--steps 300] [--rounds 5] [--venv DIR] [--json F]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

import gymnasium as gym
import numpy as np

import sim  # noqa: F401  registers drivestudio/Highway-v0
from controller.highway import ChenController
from sim.highway.gym_env import HighwayEnv

REPO = Path(__file__).resolve().parents[1]
WORKER = Path(__file__).resolve().with_name("_highway_env_worker.py")
HIGHWAY_ENV = "highway-env==1.12.1"
DEFAULT_VENV = REPO / ".venv-highway-env"


class NotAvailable(RuntimeError):
    """highway-env could not be installed or started here."""


def venv_python(venv: Path) -> Path:
    return venv / "bin" / "python"


def ensure_highway_env(venv: Path, log=print) -> Path:
    """The python of a virtual environment holding highway-env, created (about 30 s) when missing."""
    python = venv_python(venv)
    stamp = venv / ".bench-installed"
    if python.exists() and stamp.exists() and stamp.read_text().strip() == HIGHWAY_ENV:
        return python
    log(f"installing {HIGHWAY_ENV} into {venv} (once, about a minute) ...")
    env = dict(os.environ, PIP_DISABLE_PIP_VERSION_CHECK="1")
    steps = [[sys.executable, "-m", "venv", str(venv)],
             [str(python), "-m", "pip", "install", "-q", HIGHWAY_ENV]]
    for cmd in steps:
        try:
            r = subprocess.run(cmd, capture_output=True, text=True, timeout=900, env=env)
        except (OSError, subprocess.TimeoutExpired) as e:
            raise NotAvailable(f"{' '.join(cmd[:3])} failed: {e}") from None
        if r.returncode != 0:
            last = [ln for ln in (r.stderr or r.stdout).splitlines() if ln.strip() and "is ignored" not in ln]
            raise NotAvailable(f"`{' '.join(Path(c).name if i == 0 else c for i, c in enumerate(cmd))}` failed: "
                               f"{last[-1] if last else 'exit status ' + str(r.returncode)}")
    stamp.write_text(HIGHWAY_ENV + "\n")
    return python


class Theirs:
    """highway-env's highway-v0 in its own interpreter, stepped on request."""

    def __init__(self, python: Path, seed: int = 0, policy_frequency: int | None = None):
        env = dict(os.environ, SDL_VIDEODRIVER="dummy", SDL_AUDIODRIVER="dummy", PYTHONUNBUFFERED="1")
        env.pop("PYTHONPATH", None)
        extra = ["--policy-frequency", str(policy_frequency)] if policy_frequency else []
        self.proc = subprocess.Popen([str(python), str(WORKER), "--seed", str(seed), *extra], stdin=subprocess.PIPE,
                                     stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env,
                                     cwd=str(REPO))
        assert self.proc.stdin and self.proc.stdout and self.proc.stderr   # all three are pipes
        self._stdin, self._stdout, self._stderr = self.proc.stdin, self.proc.stdout, self.proc.stderr
        self.hello = self._read()
        if not self.hello.get("ready"):
            raise NotAvailable(f"highway-env did not start: {self.hello}")

    def _read(self) -> dict:
        line = self._stdout.readline()
        if not line:
            err = self._stderr.read().strip().splitlines()
            raise NotAvailable(f"highway-env's worker stopped: {err[-1] if err else 'no output'}")
        return json.loads(line)

    def run(self, steps: int) -> dict:
        self._stdin.write(json.dumps({"steps": steps}) + "\n")
        self._stdin.flush()
        return self._read()

    def close(self) -> None:
        if self.proc.poll() is None:
            self._stdin.close()
            try:
                self.proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()


class Ours:
    """drivestudio/Highway-v0 with the Chen controller on the true indicators."""

    def __init__(self, seed: int = 0):
        self.env = gym.make("drivestudio/Highway-v0", track="oval", lanes=3, cars=12, width=280, height=210)
        highway = self.env.unwrapped
        assert isinstance(highway, HighwayEnv)
        self.dt = highway.dt   # [s] simulated per step
        self.seed = seed
        self._reset()

    def _reset(self) -> None:
        self.frame, self.info = self.env.reset(seed=self.seed)
        self.ctrl = ChenController(self.info["lanes"])
        self.seed += 1

    def run(self, steps: int) -> dict:
        busy, reset_time, resets = 0.0, 0.0, 0
        for _ in range(steps):
            t0 = time.perf_counter()
            a = self.ctrl.act(self.info["indicators"], self.info["speed"])
            self.frame, _, terminated, truncated, self.info = self.env.step(np.array([a.steer, a.accel, a.brake]))
            self.frame = self.env.render()
            busy += time.perf_counter() - t0
            if terminated or truncated:
                t0 = time.perf_counter()
                self._reset()
                reset_time += time.perf_counter() - t0
                resets += 1
        return {"steps": steps, "seconds": busy, "reset_seconds": reset_time, "resets": resets,
                "frame": list(self.frame.shape)}

    def close(self) -> None:
        self.env.close()


def compare(steps: int, rounds: int, python: Path, warmup: int = 20, log=print,
            policy_frequency: int | None = None) -> dict:
    theirs = Theirs(python, policy_frequency=policy_frequency)
    try:
        ours = Ours()
        try:
            ours.run(warmup)
            theirs.run(warmup)
            rows = []
            for k in range(rounds):
                a = ours.run(steps)
                b = theirs.run(steps)
                row = {"ours_steps_per_s": a["steps"] / a["seconds"], "theirs_steps_per_s": b["steps"] / b["seconds"],
                       "ours_resets": a["resets"], "theirs_resets": b["resets"]}
                row["ratio"] = row["ours_steps_per_s"] / row["theirs_steps_per_s"]
                rows.append(row)
                log(f"  round {k + 1}/{rounds}: ours {row['ours_steps_per_s']:.0f} steps/s, highway-env "
                    f"{row['theirs_steps_per_s']:.0f} steps/s, ratio {row['ratio']:.2f}", flush=True)
            frames = (a["frame"], b["frame"])
        finally:
            ours.close()
    finally:
        theirs.close()
    med = {k: statistics.median(r[k] for r in rows) for k in ("ours_steps_per_s", "theirs_steps_per_s")}
    cfg = theirs.hello["config"]
    dt_ours, dt_theirs = ours.dt, 1.0 / cfg["policy_frequency"]
    return {"measured": True, "steps_per_round": steps, "rounds": rows,
            "ours_steps_per_s": med["ours_steps_per_s"], "theirs_steps_per_s": med["theirs_steps_per_s"],
            "ratio": med["ours_steps_per_s"] / med["theirs_steps_per_s"],
            "ratio_range": [min(r["ratio"] for r in rows), max(r["ratio"] for r in rows)],
            # a step is not the same simulated time on both sides: ours 0.1 s, highway-v0's 1 / policy_frequency
            "ours_realtime_factor": med["ours_steps_per_s"] * dt_ours,
            "theirs_realtime_factor": med["theirs_steps_per_s"] * dt_theirs,
            "ours": {"env": "drivestudio/Highway-v0", "track": "oval", "lanes": 3, "cars": 12,
                     "driver": "Chen controller on the true indicators", "frame": frames[0],
                     "seconds_per_step": dt_ours, "frames_per_step": 1},
            "theirs": {"env": "highway-v0", "action": "IDLE", "frame": frames[1], "seconds_per_step": dt_theirs,
                       "frames_per_step": cfg["simulation_frequency"] // cfg["policy_frequency"], **theirs.hello}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--steps", type=int, default=300, help="steps of each side per round (default 300)")
    ap.add_argument("--rounds", type=int, default=5, help="alternations (default 5)")
    ap.add_argument("--policy-frequency", type=int, default=None,
                    help="highway-v0's decisions per simulated second (default: its own, 1; 10 matches our step "
                         "of 0.1 s in decisions, 15 gives one simulation frame a step)")
    ap.add_argument("--venv", type=Path, default=DEFAULT_VENV,
                    help="highway-env's own virtual environment (created when missing)")
    ap.add_argument("--json", type=Path, help="also write the figures to this JSON file")
    args = ap.parse_args(argv)
    try:
        python = ensure_highway_env(args.venv)
        print(f"drivestudio/Highway-v0 (oval, 3 lanes, 12 cars, Chen on the truth, 280x210 3-D frame) vs "
              f"highway-env highway-v0 (3 lanes, 12 vehicles, IDLE, 280x210 rgb_array): {args.rounds} rounds "
              f"of {args.steps} steps each, alternating", flush=True)
        result = compare(args.steps, args.rounds, python, policy_frequency=args.policy_frequency)
    except NotAvailable as e:
        print(f"highway-env comparison not measured: {e}")
        result = {"measured": False, "reason": str(e)}
    else:
        v = result["theirs"]["versions"]
        print(f"ours {result['ours_steps_per_s']:.0f} steps/s, highway-env {v['highway-env']} "
              f"{result['theirs_steps_per_s']:.0f} steps/s (medians over {args.rounds} rounds): ratio ours/theirs "
              f"{result['ratio']:.2f} (rounds {result['ratio_range'][0]:.2f}-{result['ratio_range'][1]:.2f})")
        n = result["theirs"]["frames_per_step"]
        print(f"a step is {result['ours']['seconds_per_step']:g} simulated s for ours, "
              f"{result['theirs']['seconds_per_step']:.3g} s for highway-v0 (policy_frequency "
              f"{result['theirs']['config']['policy_frequency']}: {n} simulation frame" +
              ("s, each drawn once render() has been called" if n > 1 else "") + "): x real time, ours "
              f"{result['ours_realtime_factor']:.1f}, highway-env {result['theirs_realtime_factor']:.1f}")
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
