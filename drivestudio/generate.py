"""Dataset generation for any declared world: episodes of expert driving recorded into shards, in parallel and
resumable.

The plan is a pure function of the options (the world's Plugin.plan): episode k always has the same parameters
and seed, and so the same frames. Workers record whole episodes into shards (written atomically); the manifest
lists the finished ones with their size and SHA-256. Running the same command again after Ctrl-C or SIGKILL checks
the listed shards (a damaged one is regenerated), skips finished episodes, adopts shards that were renamed into
place just before the manifest could list them, and deletes half-written temporaries: no step is lost, duplicated
or half-written.

Every episode is a job of the pool (drivestudio/pool.py): on local worker processes (`--workers`) or as Ray tasks
(`--backend ray`); the same bytes either way.
"""
from __future__ import annotations

import fcntl
import importlib
import importlib.metadata
import json
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path

from tqdm import tqdm

from core.files import make_dir
from drivestudio import worlds
from drivestudio.errors import UsageError
from drivestudio.loop import StepRecord, in_process, run_loop
from drivestudio.pool import Job, Pool
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
from sim.camera import DEFAULT_RENDERER

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
    renderer: str = DEFAULT_RENDERER
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


# --- the jobs of the pool ------------------------------------------------------------------------------------
def job_name(args: dict) -> str:
    return f"episode {args['episode']['index']}"


def record_job(args: dict, progress) -> dict:
    """One episode as a job of the pool (drivestudio/pool.py), on a local worker or a Ray task: plain data in
    ({"ref", "episode", "config", "out"}: the world's plugin is loaded by its "module:Class" reference), its shard's
    manifest entry out."""
    return record_episode(load_plugin(args["ref"]), Episode(**args["episode"]), GenerateConfig(**args["config"]),
                          args["out"], progress=progress)


def _run(todo: list[Episode], cfg: GenerateConfig, out: Path, workers: int, backend: str, ref: str, on_done,
         on_frames) -> None:
    """The episodes as jobs of the pool; the folder must be the same path on every node of a cluster."""
    config = json.loads(json.dumps(asdict(cfg)))   # plain data, as it comes back from JSON
    jobs = [Job(job_name(args), call="drivestudio.generate:record_job", args=args)
            for ep in todo for args in [{"ref": ref, "episode": asdict(ep), "config": config,
                                         "out": str(out.resolve())}]]
    Pool(backend, slots=workers, stop_wait=0).run(jobs, on_progress=on_frames, on_done=on_done)


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

        try:
            if todo:
                _run(todo, cfg, out, workers, backend, ref, on_done, bar.update)
        finally:
            bar.close()
        manifest["complete"] = len(manifest["shards"]) == len(episodes)
        write_manifest(out, manifest)
        return manifest
    finally:
        fcntl.flock(lock, fcntl.LOCK_UN)
        lock.close()

