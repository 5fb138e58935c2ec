"""Running a benchmark: every route with every model, in parallel worker processes, then the leaderboard.

Workers are plain child processes (`python -m drivestudio.benchmark worker`, as generate's) that take one
(route, model) job at a time as a JSON line on stdin and answer with JSON lines on stdout: progress in simulated
seconds, the route's result, or an error. Each route builds its world afresh from the route's seed, so a route
drives the same whichever worker takes it and whatever ran before it in that worker; torch runs one thread per
worker (parallelism comes from the routes), so the same model gives the same scores run after run.
"""
from __future__ import annotations

import ctypes
import json
import os
import platform
import selectors
import signal
import subprocess
import sys
import time
from dataclasses import asdict
from pathlib import Path

from ..errors import RunError
from .models import ModelSpec, slug
from .route import RunOptions, run_route
from .suite import Route, Suite

STOP_WAIT = 5.0    # [s] a worker told to stop (SIGTERM) gets this long to unwind before it is killed
THREADS_ENV = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


def _die_with_parent() -> None:
    try:  # PR_SET_PDEATHSIG: a SIGKILLed parent takes its workers with it
        ctypes.CDLL(None).prctl(1, signal.SIGKILL)
    except (OSError, AttributeError):
        pass


def run_job(job: dict, progress=None) -> dict:
    """One route with one model (in a worker, or in this process)."""
    route = Route(**job["route"])
    model = ModelSpec.from_dict(job["model"])
    opts = RunOptions(**job["options"])
    clip_dir = Path(job["out"]) / "clips" / job["slug"] if opts.clips else None
    result = run_route(route, model, opts, clip_dir, progress)
    for c in result["clips"]:
        c["file"] = f"clips/{job['slug']}/{c['file']}"
    return result


def worker_main() -> int:
    """A worker: jobs as JSON lines on stdin; {"progress": s}, {"done": result} or {"error": line} on stdout."""
    from shm_bridge.signals import exit_on_sigterm
    _die_with_parent()
    if os.getppid() == 1:
        return 1
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C reaches the whole group: the parent stops us
    out_stream = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)   # library chatter must not corrupt the protocol

    def send(obj) -> None:
        out_stream.write(json.dumps(obj) + "\n")

    with exit_on_sigterm():   # SIGTERM from the parent unwinds: worlds, bridges and half-written clips are closed
        for line in sys.stdin:
            job = json.loads(line)
            try:
                if job["model"]["path"] is not None:
                    import torch
                    torch.set_num_threads(1)
                send({"done": run_job(job, progress=lambda s: send({"progress": s}))})
            except Exception as e:  # the parent stops the run with this line
                send({"error": f"route {job['route']['name']}, model {job['model']['text']}: "
                               f"{type(e).__name__}: {e}"})
    return 0


def jobs_for(suite: Suite, models: list[ModelSpec], opts: RunOptions, out: Path) -> list[dict]:
    """Every (route, model) pair, the costliest first (checkpoints perceive every frame; long routes), so that
    the workers finish together."""
    taken: set[str] = set()
    slugs = {m.key: slug(m, taken) for m in models}
    jobs = [{"route": asdict(r), "model": m.as_dict(), "options": asdict(opts), "out": str(out),
             "slug": slugs[m.key]} for m in models for r in suite.routes]
    return sorted(jobs, key=lambda j: -j["route"]["seconds"] * (1 if j["model"]["path"] is None else 8))


def run_jobs(jobs: list[dict], workers: int, on_progress, on_done) -> None:
    """Run the jobs on `workers` worker processes; on_progress(simulated seconds), on_done(result)."""
    env = dict(os.environ, PYTHONUNBUFFERED="1", **THREADS_ENV)
    procs = [subprocess.Popen([sys.executable, "-m", "drivestudio.benchmark", "worker"], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, env=env, cwd=os.getcwd())
             for _ in range(max(1, min(workers, len(jobs))))]
    queue = list(jobs)
    busy: dict = {}
    pending: dict = {p: b"" for p in procs}
    sel = selectors.DefaultSelector()

    def give(proc) -> None:
        if queue:
            job = queue.pop(0)
            proc.stdin.write((json.dumps(job) + "\n").encode())
            proc.stdin.flush()
            busy[proc] = job
        else:
            proc.stdin.close()

    def handle(proc, line: bytes) -> None:
        msg = json.loads(line)
        if "progress" in msg:
            on_progress(msg["progress"])
        elif "done" in msg:
            busy.pop(proc)
            on_done(msg["done"])
            give(proc)
        else:
            raise RunError(msg.get("error", "a worker failed"))

    try:
        for p in procs:
            sel.register(p.stdout, selectors.EVENT_READ, p)
            give(p)
        while busy:
            for key, _ in sel.select(timeout=1.0):
                proc = key.data
                chunk = os.read(proc.stdout.fileno(), 1 << 16)
                if not chunk:
                    sel.unregister(proc.stdout)
                    if proc in busy:
                        job = busy[proc]
                        raise RunError(f"a worker died driving route {job['route']['name']} with "
                                       f"{job['model']['text']} (exit status {proc.wait()})")
                    continue
                *lines, pending[proc] = (pending[proc] + chunk).split(b"\n")
                for line in lines:
                    handle(proc, line)
        for p in procs:
            p.wait(timeout=30)
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate()
        for p in procs:
            try:
                p.wait(timeout=STOP_WAIT)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        sel.close()


def run_benchmark(suite: Suite, models: list[ModelSpec], opts: RunOptions, out: Path, workers: int,
                  show_progress: bool = True) -> dict:
    """Drive the suite with every model; returns the leaderboard (score.leaderboard) with the run's facts."""
    from tqdm import tqdm

    from shm_bridge.signals import exit_on_sigterm

    from .score import leaderboard
    jobs = jobs_for(suite, models, opts, out)
    results: list[dict] = []
    total = sum(j["route"]["seconds"] for j in jobs)
    bar = tqdm(total=round(total), unit="sim s", disable=not show_progress, file=sys.stderr, dynamic_ncols=True,
               smoothing=0.05, desc=f"{len(suite.routes)} routes x {len(models)} models")
    t0 = time.perf_counter()
    try:
        with exit_on_sigterm():
            run_jobs(jobs, workers, lambda s: bar.update(s), results.append)
    finally:
        bar.close()
    board = leaderboard(suite, models, results)
    board["run"] = {"transport": opts.transport, "workers": max(1, min(workers, len(jobs))),
                    "wall_time_s": round(time.perf_counter() - t0, 1), "device": opts.device,
                    "renderer": opts.renderer, "clips_per_route": opts.clips, "python": platform.python_version(),
                    "machine": f"{platform.machine()}, {os.cpu_count()} cores", "threads_per_worker": 1}
    return board
