"""Dataset generation for any declared world: episodes of expert driving recorded into shards, in parallel and
resumable.

The plan is a pure function of the options (the world's Plugin.plan): episode k always has the same parameters
and seed, and so the same frames. Workers record whole episodes into shards (written atomically); the manifest
lists the finished ones with their size and SHA-256. Running the same command again after Ctrl-C or SIGKILL checks
the listed shards (a damaged one is regenerated), skips finished episodes, adopts shards that were renamed into
place just before the manifest could list them, and deletes half-written temporaries: no step is lost, duplicated
or half-written.

Local workers are plain child processes (`python -m drivestudio.generate worker`) that read episodes and write
results as JSON lines on pipes: no POSIX semaphores or shared memory, so a kill -9 leaves nothing in /dev/shm.
"""
from __future__ import annotations

import fcntl
import importlib
import importlib.metadata
import json
import os
import platform
import socket
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from tqdm import tqdm

from core.files import make_dir
from drivestudio import worlds
from drivestudio.errors import RunError, UsageError
from drivestudio.loop import StepRecord, in_process, run_loop
from drivestudio.worker_pool import run_pool, serve
from drivestudio.worlds import Episode, Plugin
from perception.shards import (
    MANIFEST,
    SPLIT_RULE,
    DatasetError,
    ShardInfo,
    ShardReader,
    ShardWriter,
    clean_temporaries,
    file_digest,
    manifest_declaration,
    read_manifest,
    shard_name,
    split_of,
    verify_shard,
    write_manifest,
)

PROGRESS_EVERY = 25  # steps between progress reports from a worker
MIN_EPISODES = 10    # the split rule takes every tenth episode: fewer would leave the validation or test split empty
MIN_EPISODE_FRAMES = 20
DEFAULT_EPISODE_FRAMES = 500


def episode_length(frames: int, episode_frames: int | None) -> int:
    """The steps an episode records: --episode-frames when the user gave it; otherwise DEFAULT_EPISODE_FRAMES,
    shortened (to no less than MIN_EPISODE_FRAMES) so that a small dataset still has MIN_EPISODES episodes and
    every split holds frames (600 frames: 10 episodes of 60)."""
    if episode_frames is not None:
        return episode_frames
    return max(MIN_EPISODE_FRAMES, min(DEFAULT_EPISODE_FRAMES, -(-frames // MIN_EPISODES)))


@dataclass(frozen=True)
class GenerateConfig:
    """Everything that decides the content of a dataset (and nothing that does not, like the worker count)."""

    world: str = "highway"
    frames: int = 20000
    seed: int = 0
    renderer: str = "tiny"
    encoding: str = "png"
    quality: int = 95
    episode_frames: int | None = None   # None: DEFAULT_EPISODE_FRAMES, shortened for small datasets
    warmup: float = 5.0               # [s] driven before recording starts
    options: dict = field(default_factory=dict)   # the world's own (Plugin.generate_options)


def plugin_ref(plugin: Plugin) -> str:
    """Where a worker process finds the world's plugin: "module:Class"."""
    cls = type(plugin)
    return f"{cls.__module__}:{cls.__qualname__}"


def load_plugin(ref: str) -> Plugin:
    module, _, name = ref.partition(":")
    plugin = getattr(importlib.import_module(module), name)()
    return worlds.register(plugin)


def plan(cfg: GenerateConfig) -> list[Episode]:
    return worlds.get(cfg.world).plan(cfg.options, cfg.frames, episode_length(cfg.frames, cfg.episode_frames),
                                      cfg.seed)


def record_episode(plugin: Plugin, ep: Episode, cfg: GenerateConfig, out: str,
                   progress: Callable[[int], object] | None = None) -> dict:
    """Drive one episode with the world's expert and write its shard; returns the manifest entry."""
    world, expert, columns = plugin.episode(ep, cfg.options, cfg.renderer)
    try:
        act = in_process(expert)
        run_loop(world, act, cfg.warmup, render=False, when_lost="recover")
        writer = ShardWriter(Path(out) / shard_name(ep.index), world.declaration, cfg.encoding, cfg.quality)

        def on_step(rec: StepRecord) -> None:
            obs = rec.obs
            writer.add(obs.frames, obs.record, columns(obs), episode=ep.index, step=len(writer), t=obs.t,
                       seed=ep.seed, action=rec.action)
            if progress is not None and len(writer) % PROGRESS_EVERY == 0:
                progress(PROGRESS_EVERY)

        run_loop(world, act, ep.frames * world.dt, render=True, on_step=on_step, when_lost="recover")
        written = writer.close()
        if progress is not None:
            progress(written["frames"] % PROGRESS_EVERY)
    finally:
        world.close()
    return ShardInfo(shard_name(ep.index), ep.index, written["frames"], split_of(ep.index), dict(ep.params),
                     written["size"], written["sha256"]).entry()


# --- the run -------------------------------------------------------------------------------------------------
def _software() -> dict:
    out: dict[str, str | None] = {"python": platform.python_version()}
    for pkg in ("drivestudio", "pybullet", "libsumo", "numpy", "opencv-python-headless", "pyarrow", "trimesh"):
        try:
            out[pkg] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[pkg] = None
    return out


def _config_dict(cfg: GenerateConfig) -> dict:
    return json.loads(json.dumps(asdict(cfg)))   # tuples become lists, as they come back from the manifest


def _open_manifest(out: Path, cfg: GenerateConfig, plugin: Plugin) -> dict:
    config = _config_dict(cfg)
    if (out / MANIFEST).exists():
        manifest = read_manifest(out)
        if manifest.get("version") == 1:
            raise UsageError(f"{out} holds a dataset of format version 1; give a new --out (this version writes "
                             "format 2)")
        if manifest.get("config") != config:
            old = manifest.get("config", {})
            diff = sorted(k for k in set(old) | set(config) if old.get(k) != config.get(k))
            raise UsageError(f"{out} holds a dataset made with other options ({', '.join(diff)} differ); "
                             f"give the same options to continue it, or a new --out")
        return manifest
    if any(out.glob("shard-*.parquet")):
        raise UsageError(f"{out} holds shards but no {MANIFEST}; it is not a dataset this command can continue")
    decl = plugin.declaration_for(cfg.options)
    return {"world": decl.to_json(), "config": config, "seed": cfg.seed, "renderer": cfg.renderer,
            "split_rule": SPLIT_RULE, "episode_frames": episode_length(cfg.frames, cfg.episode_frames),
            "software": _software(), "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
            "shards": [], "frames": 0, "complete": False}


def _check_listed(out: Path, manifest: dict, log) -> None:
    """Shards the manifest lists but that are missing or damaged (truncated, changed): forget them, so that their
    episodes are recorded again. A whole shard (its checksum the manifest's) that is not one of this dataset's
    (another world's columns, another length) is refused: the manifest was made for other files."""
    if not manifest["shards"]:
        return
    decl = manifest_declaration(manifest)
    keep = []
    for entry in manifest["shards"]:
        info = ShardInfo.from_entry(entry)
        problem = verify_shard(out, info)
        if problem is None:
            _check_fits(out, info, decl)
            keep.append(entry)
            continue
        log(f"shard {info.file} is damaged ({problem}): recording episode {info.episode} again")
        (out / info.file).unlink(missing_ok=True)
    manifest["shards"] = keep


def _check_fits(out: Path, info: ShardInfo, decl) -> None:
    try:
        frames = len(ShardReader(out / info.file, decl))
    except DatasetError as e:
        raise DatasetError(f"{e}, yet {out}/{MANIFEST} lists it with its checksum: not a dataset this command can "
                           "continue (give a new --out)") from None
    if frames != info.frames:
        raise DatasetError(f"shard {out / info.file} holds {frames} frames, yet {out}/{MANIFEST} lists it with "
                           f"{info.frames} and its checksum: not a dataset this command can continue (give a new "
                           "--out)")


def _adopt_orphans(out: Path, manifest: dict, episodes: list[Episode]) -> None:
    """Shards renamed into place by a run killed before it could list them: keep them if they are whole."""
    listed = {s["episode"] for s in manifest["shards"]}
    decl = manifest_declaration(manifest)
    for ep in episodes:
        path = out / shard_name(ep.index)
        if ep.index in listed or not path.exists():
            continue
        try:
            ok = len(ShardReader(path, decl)) == ep.frames
        except DatasetError:
            ok = False
        if ok:
            size, digest = file_digest(path)
            manifest["shards"].append(ShardInfo(path.name, ep.index, ep.frames, split_of(ep.index), dict(ep.params),
                                                size, digest).entry())
        else:
            path.unlink()


# --- local workers -------------------------------------------------------------------------------------------
def _episode_name(job: dict) -> str:
    return f"episode {job['episode']['index']}"


def _record_job(job: dict, progress) -> dict:
    return record_episode(load_plugin(job["ref"]), Episode(**job["episode"]), GenerateConfig(**job["config"]),
                          job["out"], progress=progress)


def worker_main() -> int:
    """A local worker (worker_pool): jobs {"ref", "episode", "config", "out"}, results: shard entries."""
    return serve(_record_job, _episode_name)


def _run_local(todo: list[Episode], cfg: GenerateConfig, out: Path, workers: int, ref: str, on_done,
               on_frames) -> None:
    jobs = [{"ref": ref, "episode": asdict(ep), "config": asdict(cfg), "out": str(out)} for ep in todo]
    run_pool("drivestudio.generate", jobs, workers, on_frames, on_done, _episode_name)


def _check_reachable(address: str | None, timeout: float = 10.0) -> None:
    """RAY_ADDRESS=host:port (or ray://host:port) must answer: ray.init would otherwise retry for minutes."""
    if not address or address == "auto":
        return
    host, _, port = address.split("://")[-1].rpartition(":")
    if not host or not port.isdigit():
        return
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as e:
        raise RunError(f"--backend ray: no Ray cluster answers at RAY_ADDRESS={address} ({e.strerror or e}); start "
                       "one with `ray start --head` (docs/scaling.md)") from None


def ray_record_episode(ref: str, episode: dict, config: dict, out: str) -> dict:
    """A Ray task: record one episode on whichever node runs it (module level, so that the workers import it by
    reference; the world's plugin is loaded there by its "module:Class" reference)."""
    return record_episode(load_plugin(ref), Episode(**episode), GenerateConfig(**config), out)


def _run_ray(todo: list[Episode], cfg: GenerateConfig, out: Path, ref: str, on_done) -> None:
    try:
        import ray  # lazy: an optional extra, seconds to import; without it, one clear line
    except ImportError:
        raise UsageError("--backend ray needs Ray: pip install 'drivestudio[cluster]' (and a folder every node "
                         "can write to as --out)") from None
    address = os.environ.get("RAY_ADDRESS")
    _check_reachable(address)
    env_vars = {k: os.environ[k] for k in ("DRIVESTUDIO_WORLDS",) if os.environ.get(k)}
    started = not ray.is_initialized()
    try:
        ray.init(address=address, ignore_reinit_error=True, log_to_driver=False,
                 runtime_env={"env_vars": env_vars} if env_vars else None)
    except (ConnectionError, RuntimeError, ValueError) as e:
        raise RunError(f"--backend ray: cannot reach the Ray cluster at {address or '(a new local one)'}: "
                       f"{str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__}") from None
    try:
        remote = ray.remote(num_cpus=1, max_retries=2)(ray_record_episode)
        # plain data only, as the local workers get it (JSON); the folder must be the same path on every node
        config = json.loads(json.dumps(asdict(cfg)))
        pending = {remote.remote(ref, asdict(ep), config, str(out.resolve())): ep for ep in todo}
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            ep = pending.pop(done[0])
            try:
                entry = ray.get(done[0])
            except ray.exceptions.RayError as e:
                for rest in pending:
                    ray.cancel(rest, force=True)
                cause = getattr(e, "cause", None) or e
                raise RunError(f"episode {ep.index} failed on the Ray cluster: {type(cause).__name__}: "
                               f"{str(cause).strip().splitlines()[-1] if str(cause).strip() else ''}") from None
            on_done(entry)
    finally:
        if started:
            ray.shutdown()


def generate(out: Path, cfg: GenerateConfig, workers: int = 2, backend: str = "local",
             show_progress: bool = True, log=print, plugin: Plugin | None = None) -> dict:
    """Make (or continue) the dataset in `out`; returns its manifest. `plugin`: the world's plugin, or one that
    drives its episodes otherwise (data aggregation's); its workers load it by its module and class."""
    plugin = plugin or worlds.get(cfg.world)
    ref = plugin_ref(plugin)
    out = make_dir(Path(out))
    lock = open(out / ".lock", "w")
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        raise UsageError(f"another generate run is writing to {out}") from None
    try:
        clean_temporaries(out)
        manifest = _open_manifest(out, cfg, plugin)
        episodes = plan(cfg)
        _check_listed(out, manifest, log)
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
                _run_ray(todo, cfg, out, ref, on_done)
            elif todo:
                _run_local(todo, cfg, out, workers, ref, on_done, bar.update)
        finally:
            bar.close()
        manifest["complete"] = len(manifest["shards"]) == len(episodes)
        write_manifest(out, manifest)
        return manifest
    finally:
        fcntl.flock(lock, fcntl.LOCK_UN)
        lock.close()


if __name__ == "__main__":
    if sys.argv[1:] == ["worker"]:
        sys.exit(worker_main())
    sys.exit("usage: python -m drivestudio.generate worker (started by `drivestudio generate`)")
