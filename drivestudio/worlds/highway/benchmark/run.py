"""Running a benchmark: every route with every model as jobs of the pool (drivestudio/pool.py), then the leaderboard.

Each (route, model) pair is one job: on a local worker process (`--workers` of them) or a Ray task (`--backend
ray`), reporting its progress in simulated seconds and answering with the route's result. Each route builds its
world afresh from the route's seed, so a route drives the same whichever worker takes it and whatever ran before it
in that worker; torch runs one thread per worker (parallelism comes from the routes), so the same model gives the
same scores run after run, on either backend.
"""
from __future__ import annotations

import os
import platform
import sys
import time
from dataclasses import asdict
from pathlib import Path

from core.signals import exit_on_sigterm
from drivestudio.pool import ONE_THREAD, Job, Pool
from drivestudio.worlds.highway.benchmark.models import ModelSpec, slug
from drivestudio.worlds.highway.benchmark.route import RunOptions, run_route
from drivestudio.worlds.highway.benchmark.suite import Route, Suite

STOP_WAIT = 5.0    # [s] a worker told to stop (SIGTERM) gets this long to unwind before it is killed


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


def job_name(job: dict) -> str:
    return f"route {job['route']['name']}, model {job['model']['text']}"


def drive_job(job: dict, progress) -> dict:
    """One job of the pool: one route with one model, torch on one thread (the parallelism is the routes')."""
    if job["model"]["path"] is not None:
        import torch  # lazy: torch, only to set its threads in a worker
        torch.set_num_threads(1)
    return run_job(job, progress)


def jobs_for(suite: Suite, models: list[ModelSpec], opts: RunOptions, out: Path) -> list[dict]:
    """Every (route, model) pair, the costliest first (checkpoints perceive every frame; long routes), so that
    the workers finish together."""
    taken: set[str] = set()
    slugs = {m.key: slug(m, taken) for m in models}
    jobs = [{"route": asdict(r), "model": m.as_dict(), "options": asdict(opts), "out": str(out),
             "slug": slugs[m.key]} for m in models for r in suite.routes]
    return sorted(jobs, key=lambda j: -j["route"]["seconds"] * (1 if j["model"]["path"] is None else 8))


def run_jobs(jobs: list[dict], workers: int, on_progress, on_done, backend: str = "local") -> None:
    """Run the jobs on `workers` worker processes, or as Ray tasks; on_progress(simulated seconds), on_done(result)."""
    Pool(backend, slots=workers, env=ONE_THREAD, stop_wait=STOP_WAIT).run(
        [Job(job_name(j), call="drivestudio.worlds.highway.benchmark.run:drive_job", args=j) for j in jobs],
        on_progress=on_progress, on_done=on_done)


def drive_all(jobs: list[dict], workers: int, desc: str, show_progress: bool = True, backend: str = "local") -> list:
    """Every job's result, in the order they finish, a bar of simulated seconds on stderr while they run."""
    from tqdm import tqdm  # lazy: 20 ms, only while routes are driven

    results: list[dict] = []
    bar = tqdm(total=round(sum(j["route"]["seconds"] for j in jobs)), unit="sim s", disable=not show_progress,
               file=sys.stderr, dynamic_ncols=True, smoothing=0.05, desc=desc)
    try:
        with exit_on_sigterm():
            run_jobs(jobs, workers, lambda s: bar.update(s), results.append, backend)
    finally:
        bar.close()
    return results


def run_benchmark(suite: Suite, models: list[ModelSpec], opts: RunOptions, out: Path, workers: int,
                  show_progress: bool = True, backend: str = "local") -> dict:
    """Drive the suite with every model; returns the leaderboard (score.leaderboard) with the run's facts."""
    from drivestudio.worlds.highway.benchmark.score import leaderboard  # lazy: only once routes are driven
    jobs = jobs_for(suite, models, opts, out.resolve())   # on a cluster, the same path on every node
    t0 = time.perf_counter()
    results = drive_all(jobs, workers, f"{len(suite.routes)} routes x {len(models)} models", show_progress, backend)
    board = leaderboard(suite, models, results)
    board["run"] = {"transport": opts.transport, "workers": max(1, min(workers, len(jobs))),
                    "wall_time_s": round(time.perf_counter() - t0, 1), "device": opts.device,
                    "renderer": opts.renderer, "condition": opts.condition, "clips_per_route": opts.clips,
                    "python": platform.python_version(),
                    "machine": f"{platform.machine()}, {os.cpu_count()} cores", "threads_per_worker": 1}
    return board
