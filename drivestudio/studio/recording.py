"""Recording what is driven in the studio as a dataset of the project's format (docs/dataset.md), which `stats`,
`train`, `evaluate` and the correction rounds read like one `generate` wrote.

Steps are cut into episodes of `shard_steps` steps (and at every reset, which starts a new scene); each episode is
one shard, written atomically by perception/shards.py's ShardWriter, and the manifest is replaced after each
shard. So a recording killed at any moment (even by SIGKILL) is a dataset up to its last whole shard; stopped in
order, the last, shorter episode is written too, unless it is shorter than MIN_EPISODE_STEPS (a stop or a reset
right after an episode's end): steps that few make no episode a model learns from, so they are left out and said
to be. The split rule is the generator's: episode % 10 decides.

Shards are written by a background thread, so that the loop does not stall while one is saved.
"""
from __future__ import annotations

import time
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

from core.declaration import WorldDeclaration
from core.files import make_dir
from drivestudio.errors import UsageError
from drivestudio.loop import StepRecord
from perception.shards import MANIFEST, SPLIT_RULE, ShardInfo, ShardWriter, shard_name, split_of, write_manifest

DEFAULT_SHARD_STEPS = 300     # 10 s of the sidewalk, 30 s of the highway
MIN_EPISODE_STEPS = 10        # a shorter last episode (cut by a stop or a reset) is left out


class DatasetRecorder:
    """One recording: a dataset folder that grows by one shard per episode."""

    def __init__(self, root: Path, decl: WorldDeclaration, meta: dict, shard_steps: int = DEFAULT_SHARD_STEPS):
        root = Path(root)
        if (root / MANIFEST).exists() or (root.is_dir() and any(root.iterdir())):
            raise UsageError(f"{root} already holds files; record under another name")
        self.root = make_dir(root)
        self.decl, self.shard_steps = decl, shard_steps
        self.manifest = {"world": decl.to_json(), **meta, "split_rule": SPLIT_RULE,
                         "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "shards": [], "frames": 0,
                         "complete": False}
        self._writer: ShardWriter | None = None
        self._params: dict = {}
        self._episode = 0
        self.steps = 0
        self.left_out = 0         # steps of episodes too short to keep
        self._saver = ThreadPoolExecutor(max_workers=1, thread_name_prefix="studio-shards")
        self._pending: list[Future] = []
        write_manifest(self.root, self.manifest)

    def add(self, rec: StepRecord, columns: dict, params: dict, seed: int) -> None:
        """One step; `params` says what the episode is (track or path, seed, who drove)."""
        if self._writer is None:
            self._writer = ShardWriter(self.root / shard_name(self._episode), self.decl)
            self._params = dict(params)
        else:
            for who in params.get("drivers", []):
                if who not in self._params.setdefault("drivers", []):
                    self._params["drivers"].append(who)
            self._params["human_steps"] = self._params.get("human_steps", 0) + params.get("human_steps", 0)
        obs = rec.obs
        w = self._writer
        w.add(obs.frames, obs.record, columns, episode=self._episode, step=len(w), t=obs.t, seed=seed,
              action=rec.action)
        self.steps += 1
        if len(w) >= self.shard_steps:
            self.cut()

    def cut(self) -> None:
        """End the episode here (a full shard, a reset, the end): its shard is saved in the background, or, when it
        is shorter than MIN_EPISODE_STEPS, left out."""
        if self._writer is None or not len(self._writer):
            return
        if len(self._writer) < MIN_EPISODE_STEPS:
            self.steps -= len(self._writer)
            self.left_out += len(self._writer)
            self._writer = None
            return
        writer, episode, params = self._writer, self._episode, self._params
        self._writer, self._episode = None, self._episode + 1
        self._pending.append(self._saver.submit(self._save, writer, episode, params))

    def _save(self, writer: ShardWriter, episode: int, params: dict) -> None:
        written = writer.close()
        entry = ShardInfo(shard_name(episode), episode, written["frames"], split_of(episode), params,
                          written["size"], written["sha256"]).entry()
        self.manifest["shards"].append(entry)
        self.manifest["frames"] = sum(s["frames"] for s in self.manifest["shards"])
        write_manifest(self.root, self.manifest)

    @property
    def shards(self) -> int:
        return len(self.manifest["shards"])

    def close(self) -> dict:
        """Write the last episode and mark the dataset complete; returns the manifest."""
        self.cut()
        self._saver.shutdown(wait=True)
        for job in self._pending:
            job.result()   # a shard that could not be written is an error the caller reports
        self.manifest["complete"] = True
        write_manifest(self.root, self.manifest)
        return self.manifest
