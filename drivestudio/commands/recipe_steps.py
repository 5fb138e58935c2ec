"""The recipes' shared steps (drivestudio/commands/recipe.py, recipe_extended.py): the verbs a user would run,
each timed and logged, each a process of its own run by the pool (drivestudio/pool.py); the ensemble; the
benchmark, skipped when it is newer than its models."""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path

from core.conditions import CONDITIONS, SEEDED
from core.settings import setting
from drivestudio.errors import UsageError
from drivestudio.outputs import write_json
from drivestudio.pool import ONE_THREAD, Job, Pool, run_verb
from sim.camera import DEFAULT_RENDERER, RENDERERS

EXACT = ("oracle", "oracle-extended")   # benchmark rows with no model file (the drivers on exact labels)


@dataclass(frozen=True)
class RecipeRun:
    """What every recipe's settings begin with: where it writes, what it benchmarks, how many workers."""

    out: str = setting("out/recipe", "output folder")
    suite: str = setting("default", "the benchmark suite: a shipped suite's name (default, the held-out one; "
                                    "random, ...), a suite file, or none")
    workers: int = setting(2, "worker processes", low=1, high=256)


@dataclass(frozen=True)
class RecipePlan(RecipeRun):
    """...then what the driver learns from (docs/generalisation.md), as --set settings."""

    condition: str = setting(SEEDED, "the named conditions of the expert's frames: one, or a mix, each episode "
                                     "drawing one (docs/conditions.md)", choices=CONDITIONS, several=True)
    tracks: str = setting("", "the training tracks, comma-separated presets, files or procedural:SEED (empty: "
                              "generate's default, every preset and three procedural tracks)")
    protocol: str = setting("none", "a generalisation protocol (a name or file): the driver learns from its training "
                                    "conditions and tracks alone and drives its every cell instead of the suite")
    renderer: str = setting(DEFAULT_RENDERER, "the renderer of every frame: the expert's, the aggregation rounds' "
                                              "and the benchmark's (docs/rendering.md)", choices=RENDERERS)


def training_plan(run: RecipePlan) -> list[str]:
    """generate's options for the conditions and tracks the recipe's driver learns from (the aggregation rounds read
    them from the expert's dataset); a protocol's training split replaces both."""
    condition, tracks = run.condition, run.tracks
    if run.protocol != "none":
        if condition != SEEDED or tracks:
            raise UsageError(f"protocol={run.protocol} sets the training conditions and tracks; give it or "
                             "condition and tracks, not both")
        protocol = load(run.protocol)
        condition, tracks = ",".join(protocol.conditions["training"]), ",".join(protocol.tracks["training"])
    return (["--condition", condition] if condition != SEEDED else []) + (["--tracks", tracks] if tracks else []) \
        + renderer_argv(run, "--set", "renderer=")


def renderer_argv(run: RecipePlan, flag: str, prefix: str = "") -> list[str]:
    """The recipe's renderer as a verb's option (generate's `--set renderer=NAME`, the benchmark's `--renderer
    NAME`); none for the default, so that the commands read as before."""
    return [] if run.renderer == DEFAULT_RENDERER else [flag, f"{prefix}{run.renderer}"]


def load(protocol: str):
    """The protocol a recipe's `protocol` setting names; its refusal names the setting, not the benchmark's flag."""
    from drivestudio.worlds.highway.benchmark.protocol import ProtocolError, load_protocol  # lazy: the benchmark
    try:
        return load_protocol(protocol)
    except ProtocolError as e:
        raise ProtocolError(str(e).replace("--protocol ", "--set protocol=", 1)) from None


class Steps:
    """The recipe's steps as the verbs a user would run, each timed and logged to commands.txt."""

    def __init__(self, out: Path):
        self.out = out
        self.t_start = time.perf_counter()
        self.log: list[str] = []

    def header(self, title: str, argv_lines: list[list]) -> float:
        print(f"\n== {title}  ({(time.perf_counter() - self.t_start) / 60:.1f} min so far)", flush=True)
        for argv in argv_lines:
            line = "drivestudio " + " ".join(map(str, argv))
            print("$ " + line, flush=True)
            self.log.append(line)
        return time.perf_counter()

    def done(self, t0: float) -> None:
        print(f"({(time.perf_counter() - t0) / 60:.1f} min)", flush=True)

    def verb(self, title: str, *argv) -> None:
        """A verb as a process of its own, its output this one's; its failure (its one line already on stderr)
        ends the recipe with its exit status."""
        t0 = self.header(title, [list(argv)])
        run_verb(list(argv))
        self.done(t0)

    def side_by_side(self, title: str, commands: list[list], logs: list[Path],
                     after: list[int | None] | None = None) -> None:
        t0 = self.header(title, commands)
        print(f"  (one thread each; their output in {', '.join(str(log) for log in logs)}; progress every minute)",
              flush=True)
        run_side_by_side(commands, logs, after=after)
        self.done(t0)

    def minutes(self) -> float:
        return (time.perf_counter() - self.t_start) / 60


def run_side_by_side(commands: list[list], logs: list[Path], every: float = 60.0,
                     after: list[int | None] | None = None) -> None:
    """Run `drivestudio ARGV` for each of `commands` at once, one thread each, stdout and stderr into the matching log,
    but for a command i with `after[i]` (an earlier command's index), which starts when that one has succeeded;
    returns when all have succeeded, raises RunError (JobFailed) naming the first that failed (the others are
    stopped); their progress (the last `N/M` count of each log) on one line every `every` seconds. On a machine with
    fewer cores than commands, one thread each keeps the cores busy without the trainings' thread pools fighting
    (two trainings side by side on 2 cores take 1.4x one training's time, not 2x: docs/log.md); a child's
    results do not depend on what runs beside it."""
    n = len(commands)
    after = after or [None] * n
    if len(logs) != n or len(after) != n or any(a is not None and not 0 <= a < i for i, a in enumerate(after)):
        raise ValueError("one log per command, and each command after an earlier one")
    jobs = [Job(str(i), argv=[str(a) for a in argv], log=log, after=() if a is None else (str(a),))
            for i, (argv, log, a) in enumerate(zip(commands, logs, after))]
    Pool(slots=n, env=ONE_THREAD, every=every).run(jobs)


def make_ensemble(members: list[Path], ensemble: Path) -> None:
    from drivestudio.ensemble import make  # torch: only once the recipe runs
    from perception.checkpoint import save_checkpoint  # torch
    save_checkpoint(ensemble, make([str(m) for m in members]))


def ensemble_step(steps: Steps, title: str, members: list[Path], ensemble: Path) -> None:
    """The members as one ensemble, unless `ensemble` is newer than every member (made before)."""
    if ensemble.is_file() and all(m.stat().st_mtime <= ensemble.stat().st_mtime for m in members):
        return
    t0 = steps.header(title, [["ensemble", "--out", ensemble, *members]])
    make_ensemble(members, ensemble)
    steps.done(t0)


def benchmark(steps: Steps, models: list, run: RecipePlan) -> Path | None:
    """The models beside the oracle on the suite (or every cell of the protocol); skipped when its leaderboard is
    newer than every model."""
    if run.protocol != "none":
        return protocol_benchmark(steps, models, run)
    if run.suite == "none":
        return None
    bench = steps.out / "benchmark"
    board = bench / "leaderboard.md"
    if done_before(bench, run.suite, [Path(str(m).split("@")[0]) for m in models if str(m) not in EXACT]):
        print(f"\n== the benchmark: done before ({board})", flush=True)
        return board
    models_argv = [a for m in models for a in ("--model", m)]
    suite = [] if run.suite == "default" else ["--suite", run.suite]
    steps.verb("the benchmark of every model beside the oracle", "benchmark", *models_argv, *suite,
               *renderer_argv(run, "--renderer"), "--workers", run.workers, "--out", bench)
    return board


def protocol_benchmark(steps: Steps, models: list, run: RecipePlan) -> Path:
    """The models beside both oracles in every cell of the protocol; skipped when its table (of this protocol file)
    is newer than every model."""
    bench = steps.out / "protocol"
    table = bench / "protocol.md"
    files = [Path(str(m).split("@")[0]) for m in models if str(m) not in EXACT]
    try:
        drove = json.loads((bench / "protocol.json").read_text())["protocol"]["sha256"]
    except (OSError, ValueError, KeyError, TypeError):
        drove = None
    if drove == load(run.protocol).sha256 and table.is_file() and \
            all(m.stat().st_mtime < table.stat().st_mtime for m in files):
        print(f"\n== the protocol: done before ({table})", flush=True)
        return table
    steps.verb("every cell of the protocol, every model beside both oracles", "benchmark",
               *[a for m in models if str(m) not in EXACT for a in ("--model", m)], "--protocol", run.protocol,
               *renderer_argv(run, "--renderer"), "--workers", run.workers, "--out", bench)
    return table


def fingerprints(steps: Steps) -> Path:
    """fingerprints.json: the content fingerprint of every dataset and network under the recipe's folder
    (perception/fingerprint.py), so that two runs can be compared step by step (`diff`): the first that differs is
    where they parted."""
    from perception.fingerprint import dataset_fingerprint, network_fingerprint  # torch: only once the recipe runs
    from perception.shards import MANIFEST, Dataset  # pyarrow: likewise

    t0 = steps.header("the fingerprints of every dataset and network, to compare two runs", [])
    datasets = sorted(p.parent for p in steps.out.rglob(MANIFEST))
    networks = sorted(p for p in steps.out.rglob("*.pt") if p.is_file())
    # a merged set's frames are its sources' byte for byte (perception/merge.py), fingerprinted with them: its labels
    # alone (a third of the recipe's frames would otherwise be hashed twice)
    table = {"datasets": {str(d.relative_to(steps.out)): dataset_fingerprint(ds, images=not _merged(ds))
                          for d in datasets for ds in [Dataset(d)]},
             "networks": {str(n.relative_to(steps.out)): network_fingerprint(n) for n in networks}}
    path = steps.out / "fingerprints.json"
    write_json(path, table)
    steps.done(t0)
    return path


def _merged(ds) -> bool:
    return "merged" in (ds.manifest.get("config") or {})


def done_before(bench: Path, suite: str, models: list[Path]) -> bool:
    """Whether `bench` holds a leaderboard of this suite (the same file content) newer than every model file."""
    from drivestudio.worlds.highway.benchmark import load_suite  # the world's benchmark: only when asked
    board = bench / "leaderboard.json"
    try:
        drove = json.loads(board.read_text())["suite"]["sha256"]
    except (OSError, ValueError, KeyError, TypeError):
        return False
    same = drove == load_suite(None if suite == "default" else suite).sha256
    return same and all(m.stat().st_mtime < board.stat().st_mtime for m in models)
