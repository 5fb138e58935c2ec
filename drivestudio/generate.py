"""Dataset generation: episodes of perturbed expert driving, recorded into shards, in parallel and resumable.

The plan is a pure function of the options: episode k always has the same track, lane count, car count and
seed, and so the same frames. Workers record whole episodes into shards (written atomically); the manifest
lists the finished ones. Running the same command again after Ctrl-C or SIGKILL skips finished episodes,
adopts shards that were renamed into place just before the manifest could list them, and deletes
half-written temporaries: no frame is lost, duplicated or half-written.
"""
from __future__ import annotations

import ctypes
import fcntl
import importlib.metadata
import os
import platform
import queue
import signal
import sys
import time
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from dataclasses import asdict, dataclass
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from perception.shards import (MANIFEST, SPLIT_RULE, DatasetError, ShardReader, ShardWriter, clean_temporaries,
                               read_manifest, shard_name, split_of, write_manifest)
from shm_bridge.vocabulary import INDICATORS

from .errors import UsageError

PROGRESS_EVERY = 25  # frames between progress reports from a worker


@dataclass(frozen=True)
class GenerateConfig:
    """Everything that decides the content of a dataset (and nothing that does not, like the worker count)."""

    frames: int = 20000
    tracks: tuple = ()            # track references; () = every preset and `procedural` tracks
    procedural: int = 3           # procedural tracks added to the default track list
    lanes: tuple = (1, 2, 3)
    cars: tuple = (12, 30)        # AI cars per episode, drawn from this range (inclusive)
    seed: int = 0
    renderer: str = "tiny"
    width: int = 280
    height: int = 210
    fov: float = 60.0
    encoding: str = "png"
    quality: int = 95
    episode_frames: int = 500
    warmup: float = 5.0           # [s] driven before recording starts

    def track_list(self) -> list[str]:
        if self.tracks:
            return list(self.tracks)
        from sim.track import preset_names
        return preset_names() + [f"procedural:{self.seed * 1000 + i}" for i in range(self.procedural)]


@dataclass(frozen=True)
class Episode:
    index: int
    track: str
    lanes: int
    cars: int
    seed: int
    frames: int


def plan(cfg: GenerateConfig) -> list[Episode]:
    """Episode k drives lane count k mod L on track (k div L) mod T: every track meets every lane count, and
    with three lane counts the split rule's every-tenth episode cycles through them too (10 = 1 mod 3)."""
    tracks = cfg.track_list()
    n = -(-cfg.frames // cfg.episode_frames)
    episodes = []
    for k in range(n):
        rng = np.random.default_rng([cfg.seed, k, 0x6E4])
        frames = min(cfg.episode_frames, cfg.frames - k * cfg.episode_frames)
        episodes.append(Episode(k, tracks[(k // len(cfg.lanes)) % len(tracks)], int(cfg.lanes[k % len(cfg.lanes)]),
                                int(rng.integers(cfg.cars[0], cfg.cars[1] + 1)), int(rng.integers(2**31 - 1)),
                                frames))
    return episodes


def _record(ep: Episode, step: int, obs, action, label: str) -> dict:
    t = obs.truth
    rec = {name: float(v) for name, v in zip(INDICATORS, t.indicators)}
    rec.update(lanes_left=t.lanes_left, lanes=t.lanes, speed=t.speed, lane_width=t.lane_width, in_lane=t.in_lane,
               on_marking=t.on_marking, episode=ep.index, step=step, t=obs.t, track=ep.track, seed=ep.seed,
               perturbation=label, ego=t.ego.tolist(), cars=t.cars.astype(np.float32).tolist(),
               action=[action.steer, action.accel, action.brake])
    return rec


def record_episode(ep: Episode, cfg: GenerateConfig, out: str, progress=None) -> dict:
    """Drive one episode and write its shard; returns the manifest entry. Runs in a worker process."""
    from controller.expert import PerturbedExpert
    from sim.camera import CameraConfig
    from sim.world import World, WorldConfig

    from .loop import run_loop

    camera = CameraConfig(width=cfg.width, height=cfg.height, fov_deg=cfg.fov)
    world = World(WorldConfig(track=ep.track, lanes=ep.lanes, cars=ep.cars, seed=ep.seed, renderer=cfg.renderer,
                              camera=camera, render=False, start_speed=15.0))
    try:
        expert = PerturbedExpert(ep.lanes, world.track.lane_width, ep.seed, dt=world.config.dt)
        label = ["none"]

        def exchange(obs):
            t = obs.truth
            action, label[0] = expert.act(t.indicators, t.speed, float(t.ego[4]))
            return action, t.indicators

        run_loop(world, exchange, cfg.warmup, render=False, when_lost="recover")
        writer = ShardWriter(Path(out) / shard_name(ep.index), cfg.encoding, cfg.quality)

        def on_step(rec) -> None:
            writer.add(rec.obs.frame, _record(ep, len(writer), rec.obs, rec.action, label[0]))
            if progress is not None and len(writer) % PROGRESS_EVERY == 0:
                progress.put(PROGRESS_EVERY)

        run_loop(world, exchange, ep.frames * world.config.dt, render=True, on_step=on_step, when_lost="recover")
        frames = writer.close()
        if progress is not None:
            progress.put(frames % PROGRESS_EVERY)
    finally:
        world.close()
    return {"file": shard_name(ep.index), "episode": ep.index, "frames": frames, "split": split_of(ep.index),
            "track": ep.track, "lanes": ep.lanes}


# --- the run -------------------------------------------------------------------------------------------------
def _software() -> dict:
    out = {"python": platform.python_version()}
    for pkg in ("drivestudio", "pybullet", "libsumo", "numpy", "opencv-python-headless", "pyarrow", "trimesh"):
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def _config_dict(cfg: GenerateConfig) -> dict:
    d = asdict(cfg)
    d["tracks"], d["lanes"], d["cars"] = list(cfg.track_list()), list(cfg.lanes), list(cfg.cars)
    return d


def _open_manifest(out: Path, cfg: GenerateConfig) -> dict:
    config = _config_dict(cfg)
    if (out / MANIFEST).exists():
        manifest = read_manifest(out)
        if manifest.get("config") != config:
            old = manifest.get("config", {})
            diff = sorted(k for k in set(old) | set(config) if old.get(k) != config.get(k))
            raise UsageError(f"{out} holds a dataset made with other options ({', '.join(diff)} differ); "
                             f"give the same options to continue it, or a new --out")
        return manifest
    if any(out.glob("shard-*.parquet")):
        raise UsageError(f"{out} holds shards but no {MANIFEST}; it is not a dataset this command can continue")
    return {"config": config, "seed": cfg.seed, "renderer": cfg.renderer, "split_rule": SPLIT_RULE,
            "software": _software(), "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "shards": [],
            "frames": 0, "complete": False}


def _adopt_orphans(out: Path, manifest: dict, episodes: list[Episode]) -> None:
    """Shards renamed into place by a run killed before it could list them: keep them if they are whole."""
    listed = {s["episode"] for s in manifest["shards"]}
    for ep in episodes:
        path = out / shard_name(ep.index)
        if ep.index in listed or not path.exists():
            continue
        try:
            ok = len(ShardReader(path)) == ep.frames
        except DatasetError:
            ok = False
        if ok:
            manifest["shards"].append({"file": path.name, "episode": ep.index, "frames": ep.frames,
                                       "split": split_of(ep.index), "track": ep.track, "lanes": ep.lanes})
        else:
            path.unlink()


def _worker_init(progress_queue) -> None:
    global _PROGRESS
    _PROGRESS = progress_queue
    try:  # die with the parent, even when it is SIGKILLed, rather than run on as an orphan
        ctypes.CDLL(None).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        pass
    if os.getppid() == 1:
        os._exit(1)


_PROGRESS = None


def _worker_episode(ep: Episode, cfg: GenerateConfig, out: str) -> dict:
    return record_episode(ep, cfg, out, _PROGRESS)


def _run_local(todo: list[Episode], cfg: GenerateConfig, out: Path, workers: int, on_done, on_frames) -> None:
    ctx = get_context("spawn")
    progress = ctx.Queue()
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=_worker_init, initargs=(progress,))
    try:
        pending = {pool.submit(_worker_episode, ep, cfg, str(out)) for ep in todo}
        while pending:
            done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            while True:
                try:
                    on_frames(progress.get_nowait())
                except queue.Empty:
                    break
            for fut in done:
                on_done(fut.result())
    except BaseException:
        for p in list(getattr(pool, "_processes", {}).values()):
            p.kill()
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown()


def _run_ray(todo: list[Episode], cfg: GenerateConfig, out: Path, on_done) -> None:
    try:
        import ray
    except ImportError:
        raise UsageError("--backend ray needs Ray: pip install 'drivestudio[cluster]' (and a folder every node "
                         "can write to as --out)") from None
    ray.init(address=os.environ.get("RAY_ADDRESS"), ignore_reinit_error=True, log_to_driver=False)
    task = ray.remote(record_episode)
    pending = [task.remote(ep, cfg, str(out)) for ep in todo]
    while pending:
        done, pending = ray.wait(pending, num_returns=1)
        on_done(ray.get(done[0]))


def generate(out: Path, cfg: GenerateConfig, workers: int = 2, backend: str = "local",
             show_progress: bool = True) -> dict:
    """Make (or continue) the dataset in `out`; returns its manifest."""
    from tqdm import tqdm

    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    lock = open(out / ".lock", "w")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise UsageError(f"another generate run is writing to {out}") from None
    try:
        clean_temporaries(out)
        manifest = _open_manifest(out, cfg)
        episodes = plan(cfg)
        _adopt_orphans(out, manifest, episodes)
        done = {s["episode"] for s in manifest["shards"]}
        todo = [ep for ep in episodes if ep.index not in done]
        manifest["frames"] = sum(s["frames"] for s in manifest["shards"])
        write_manifest(out, manifest)
        bar = tqdm(total=cfg.frames, initial=manifest["frames"], unit="frame", disable=not show_progress,
                   file=sys.stderr, dynamic_ncols=True, smoothing=0.05,
                   desc="generating" if not done else f"continuing ({len(done)} episodes done)")

        def on_done(entry: dict) -> None:
            manifest["shards"].append(entry)
            manifest["shards"].sort(key=lambda s: s["episode"])
            manifest["frames"] = sum(s["frames"] for s in manifest["shards"])
            write_manifest(out, manifest)
            if backend == "ray":
                bar.update(entry["frames"])

        try:
            if todo and backend == "ray":
                _run_ray(todo, cfg, out, on_done)
            elif todo:
                _run_local(todo, cfg, out, workers, on_done, bar.update)
        finally:
            bar.close()
        manifest["complete"] = len(manifest["shards"]) == len(episodes)
        write_manifest(out, manifest)
        return manifest
    finally:
        fcntl.flock(lock, fcntl.LOCK_UN)
        lock.close()
