"""Percentage autonomy (Chowdhuri, Pankaj and Zipser, MultiNet, 2017): a trained network drives a sidewalk loop with
obstacles while the expert watches under a correction rule (controller/sidewalk/correction.py: `safety`, the
default, or `strict`); autonomy = (1 - correction time / elapsed time) * 100. Every run reports its take-overs and
their seconds by the clause that caused them, and the contacts begun while the expert held the wheel (there should
be none: one means the rule acted too late).

Every step of a run is recorded into a dataset (the same format as `generate`'s) with its operation mode, so the
expert's corrections can be merged into the training data: the paper's DAgger variant, which needs no labelling
after the fact. MultiNet's trainer learns only from moments whose targets the expert drove (autonomous steps are
the network's own commands, not labels). `rounds` repeats drive, merge and retrain.

A run's `condition` (docs/conditions.md; a mix: the run's seed draws one) draws the loop in a named weather or time of
day; its recording then has the `condition` column of data generated in named conditions, so the two merge.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from core.conditions import CONDITIONS, SEEDED
from core.files import check_output
from core.settings import MAX_SEED, setting
from core.worlds.sidewalk import MODES, RULES, SIDEWALK
from drivestudio import worlds
from drivestudio.errors import UsageError
from drivestudio.loop import in_process, run_loop
from drivestudio.outputs import write_json, write_text
from perception.train_outputs import side_outputs
from sim.sidewalk.config import MAX_DENSITY, SidewalkConfig, obstacles_value

HELD_OUT_PATH = "procedural:907"   # a winding 214 m park loop that generate's default plan never drives
HELD_OUT_PATHS = ("procedural:907", "procedural:913")   # and a 239 m forest loop: the study's evaluation loops
HELD_OUT_OBSTACLES = 6.0           # obstacles per 100 m


def percentage_autonomy(correction_s: float, elapsed_s: float) -> float:
    """(1 - correction time / elapsed time) * 100, the paper's equation 3."""
    if elapsed_s <= 0:
        raise ValueError("autonomy needs a run of positive length")
    return (1.0 - correction_s / elapsed_s) * 100.0


@dataclass
class RoundResult:
    round: int
    model: str
    autonomy_percent: float
    correction_s: float
    elapsed_s: float
    corrections: int
    collisions: int
    off_path_s: float
    distance_m: float
    dataset: str | None   # the recording of the run's steps (None: not recorded)
    video: str | None
    mode: str = "direct"
    path: str = HELD_OUT_PATH
    seed: int = 0
    rule: str = "safety"
    collisions_while_correcting: int = 0
    clauses: dict = field(default_factory=dict)   # {clause: {"take_overs": n, "seconds": s}}
    condition: str = SEEDED   # the one the run's seed drew from its setting

    def row(self) -> dict:
        return dict(self.__dict__)


@dataclass
class Drive:
    """One autonomy run: which network drives where, how long, under which rule."""

    model: str = setting(None, "a sidewalk checkpoint (drivestudio train --model z2color)")
    mode: str = setting("direct", "behavioural mode (the paper measured direct and furtive)", choices=MODES)
    seconds: float = setting(120.0, "simulated seconds per round", unit="s", low=0.1, high=24 * 3600.0)
    path: str = setting(HELD_OUT_PATH, "the loop (a path preset, path file or procedural:SEED; the default is held "
                                       "out of generate's default plan)")
    obstacles: float = setting(HELD_OUT_OBSTACLES, "obstacles per 100 m", low=0.0, high=MAX_DENSITY)
    seed: int = setting(0, "seed of the scene", low=0, high=MAX_SEED)
    rule: str = setting("safety", "the correction rule: safety (take over for leaving the path, an imminent "
                                  "collision, a stalled car) or strict (also for deviating from the expert)",
                        choices=RULES)
    condition: str = setting(SEEDED, "the named condition the loop is drawn in (docs/conditions.md; seeded: the "
                                     "seed's own time of day)", choices=CONDITIONS, several=True)
    device: str = setting("cpu", "torch device: cpu, cuda, cuda:N or auto")
    video: bool = setting(True, "write a video per round, marking the corrections")
    record: bool = setting(True, "record each round's steps as a dataset (corrections-K: what a retraining merges, "
                                 "about 19 MB a minute); false for a run that is only measured")


@dataclass
class Autonomy(Drive):
    """`drivestudio autonomy`'s run: a Drive, then `rounds - 1` times merge its corrections, retrain, drive again."""

    rounds: int = setting(1, "rounds of drive, merge, retrain", low=1, high=20)
    epochs: int = setting(3, "epochs of each retraining", low=1, high=1000)
    data: str | None = setting(None, "the training data to merge the corrections with (none: the checkpoint's)")
    out: str | None = setting(None, "folder for the results (none: runs/autonomy-TIME)")


def drive_round(run: Drive, out: Path, k: int, log=print) -> RoundResult:
    """The model drives, the expert corrects under the rule; the run's steps become the dataset out/corrections-k
    (unless run.record is false)."""
    from drivestudio.bridge_loop import supervised  # lazy: the bridge, only when it runs (not for --help)

    plugin: Any = worlds.get("sidewalk")   # the sidewalk's own world, driver and metrics are used as such below
    config = SidewalkConfig(path=run.path, seed=run.seed, mode=run.mode, obstacles=obstacles_value(str(run.obstacles)),
                            operation="correctional", rule=run.rule, condition=run.condition)
    spec = plugin.parse_driver(run.model)
    data_dir = out / f"corrections-{k}"
    t0 = time.perf_counter()
    with plugin.world(config) as world:
        decl = world.declaration
        driver = plugin.driver(spec, run.device, decl, run.seed)
        driver.mode = run.mode   # the network is told its behavioural mode, as the car's operator sets it
        supervisor = plugin.supervisor(world, config, spec)
        metrics = plugin.metrics(world)
        video_path = out / f"autonomy-{k}.mp4" if run.video else None
        named = f", {world.condition}" if run.condition != SEEDED else ""
        recorder = plugin.recorder(world, video_path, f"{Path(run.model).stem} ({run.mode}, {run.rule} rule{named})")
        writer = Recording(data_dir, decl, run, world.condition) if run.record else None

        def on_step(rec) -> None:
            recorder(rec)
            if writer is not None:
                writer.add(rec)

        ok = False
        try:
            run_loop(world, supervised(in_process(driver), supervisor), run.seconds, render=True, metrics=metrics,
                     on_step=on_step, when_lost="recover")
            ok = True
        finally:
            recorder.close(ok)
        report = metrics.report()
        steps, corrected = metrics.steps, metrics.correction_steps
        if writer is not None:
            writer.close()
    elapsed, correction = steps * world.dt, corrected * world.dt   # exact: the report rounds for reading
    result = RoundResult(k, str(run.model), round(percentage_autonomy(correction, elapsed), 2), round(correction, 3),
                         round(elapsed, 3), int(report["corrections"]), int(report["collisions"]),
                         float(report["off_path_time_s"]), float(report["distance_m"]),
                         str(data_dir) if writer is not None else None,
                         str(video_path) if video_path else None, run.mode, run.path, run.seed, run.rule,
                         int(report["collisions_while_correcting"]), report.get("take_overs_by_clause") or {},
                         world.condition)
    log(f"round {k}: autonomy {result.autonomy_percent:.2f} % ({correction:.1f} s of corrections in {elapsed:.1f} s, "
        f"{result.corrections} take-overs, {result.collisions} collisions, {result.collisions_while_correcting} "
        f"while correcting; {run.mode} mode on {run.path}, {run.rule} rule, {world.condition}) in "
        f"{time.perf_counter() - t0:.0f} s; steps recorded in {data_dir}")
    return result


class Recording:
    """A run's steps as a one-episode dataset in the format of `generate` (perception/shards.py). A world drawn in a
    named condition declares the `condition` column, as `generate --set condition=...` does, so the recording merges
    with such data; the seeded look's declares none and merges with the data of before."""

    def __init__(self, root: Path, decl, run: Drive, condition: str = SEEDED):
        from perception.shards import ShardWriter, shard_name  # lazy: pyarrow
        self.root, self.decl, self.run, self.condition = root, decl, run, condition
        self.writer = ShardWriter(root / shard_name(0), decl)

    def add(self, rec) -> None:
        obs = rec.obs
        columns = {"path": self.run.path, "condition": self.condition}   # the writer keeps those declared
        self.writer.add(obs.frames, obs.record, columns, episode=0, step=len(self.writer), t=obs.t,
                        seed=self.run.seed, action=rec.action)

    def close(self) -> None:
        from drivestudio.generate import _software  # lazy: pyarrow, tqdm
        from perception.shards import SPLIT_RULE, ShardInfo, shard_name, write_manifest  # lazy: pyarrow
        run = self.run
        written = self.writer.close()
        entry = ShardInfo(shard_name(0), 0, written["frames"], "train", {"path": run.path, "mode": run.mode,
                                                                           "operation": "correctional"},
                          written["size"], written["sha256"]).entry()
        write_manifest(self.root, {"world": self.decl.to_json(), "config": {"world": "sidewalk", "autonomy": {
            "model": str(run.model), "mode": run.mode, "path": run.path, "obstacles": run.obstacles,
            "seconds": run.seconds, "seed": run.seed, "rule": run.rule,
            **({"condition": run.condition} if run.condition != SEEDED else {})}},
            "seed": run.seed, "renderer": "painter", "split_rule": SPLIT_RULE, "software": _software(),
            "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "shards": [entry], "frames": written["frames"],
            "complete": True})


def retrain(current: str, roots: list[str], out: Path, epochs: int, seed: int, device: str, log=print) -> str:
    """Fine-tune `current` (its weights, its kind: MultiNet or the MTL net of one mode) for `epochs` epochs on
    `roots`, the original data first (whose held-out episodes stay the validation set) and the corrections after
    it; returns the new checkpoint."""
    from perception.checkpoint import load_checkpoint  # lazy: torch
    from perception.train import train  # lazy: torch, pyarrow
    from perception.training import config_from  # lazy: torch, pyarrow

    options = load_checkpoint(current, world="sidewalk")["spec"]["options"]
    mtl = options.get("mtl")
    modes = None if mtl else ",".join(options.get("modes_trained", [])) or None
    train(config_from(data=",".join(roots), model="z2color", out=str(out), epochs=epochs, trials=1, seed=seed,
                      device=device, init=current, mtl=mtl, modes=modes), log=log)
    return str(out)


def merge_roots(model: str, data: str | None, rounds: int) -> list[str]:
    """The datasets a retraining merges the corrections with (`data`, else the checkpoint's own), checked before
    round 0 when there will be a retraining: each a sidewalk dataset that is there."""
    from perception.checkpoint import load_checkpoint  # lazy: torch
    from perception.shards import Dataset, DatasetError  # lazy: pyarrow

    spec = load_checkpoint(model, world="sidewalk")
    roots = [r.strip() for r in (data or ",".join(spec.get("data", {}).get("roots", []))).split(",") if r.strip()]
    if rounds == 1 and data is None:
        return roots
    if not roots:
        raise UsageError("--rounds needs the training data: give --set data=DIR (the checkpoint does not record it)")
    for root in roots:
        if not Path(root).is_dir():
            raise UsageError(f"data: no dataset folder at {root}")
        try:
            world = Dataset(Path(root)).world
        except DatasetError as e:
            raise UsageError(f"data: {e}") from None
        if world != "sidewalk":
            raise UsageError(f"data: {root} is a dataset of the {world} world; {model} learns the sidewalk's")
    check_held_out(roots[0], spec["spec"]["options"])
    return roots


def check_held_out(root: str, options: dict) -> None:
    """The retraining validates on whole episodes of the first dataset, at least one held out per mode the model
    learns (perception/moments.py): each such mode needs two episodes there."""
    from perception.shards import Dataset  # lazy: pyarrow
    # the retraining's modes: the MTL net's one, else those it was trained on (all the world's when not recorded)
    modes = [options["mtl"]] if options.get("mtl") else list(options.get("modes_trained") or SIDEWALK.modes)
    episodes: dict[str, int] = {}
    for shard in Dataset(Path(root)).shards:
        mode = str(shard.params.get("mode"))
        episodes[mode] = episodes.get(mode, 0) + 1
    short = [f"{m} ({episodes.get(m, 0)})" for m in modes if episodes.get(m, 0) < 2]
    if short:
        raise UsageError(f"data: {root} has fewer than 2 episodes of mode {', '.join(short)}; the retraining "
                         "holds one out for validation")


def earlier_run(folder: Path) -> list[str]:
    """The files of an earlier autonomy run in `folder` (its round models would be taken as trained already)."""
    if not folder.is_dir():
        return []
    return sorted(p.name for p in (folder / "autonomy.json", *folder.glob("model-round*.pt")) if p.exists())


def check_rounds(drive: Drive, rounds: int) -> None:
    """A run of several rounds merges each round's recording: refused without one, before round 0."""
    if rounds > 1 and not drive.record:
        raise UsageError("--set record=false leaves a retraining nothing to merge: it goes with --rounds 1")


def check_outputs(out: Path, rounds: int, video: bool) -> None:
    """Every file the run's rounds write, checked before round 0."""
    for name in ("autonomy.md", "autonomy.json"):
        check_output(out / name, None, "report file")
    for k in range(rounds):
        if video:
            check_output(out / f"autonomy-{k}.mp4", (".mp4",), "video")
        if k:
            check_output(out / f"model-round{k}.pt", (".pt",), "round model")
            for side, what in side_outputs(out / f"model-round{k}.pt", "multinet"):   # its retraining's curves, state
                check_output(side, None, what)


def run(drive: Drive, out: Path, rounds: int = 1, epochs: int = 3, roots: list[str] | None = None,
        log=print) -> list[RoundResult]:
    """`rounds` rounds of drive, merge the corrections, retrain (fine-tuning the last model for `epochs` epochs on
    the original data `roots` plus every round's corrections); returns the autonomy of every round. autonomy.json is
    written after every round with "complete": false until the last (a run cut off says so)."""

    results: list[RoundResult] = []
    for k in range(rounds):
        results.append(drive_round(drive, out, k, log))
        write_summary(out, results, drive.mode, complete=k + 1 == rounds)
        if k + 1 == rounds:
            break
        merged = list(roots or []) + [str(r.dataset) for r in results]   # recorded: check_rounds
        log(f"round {k + 1}: retraining on {len(merged)} dataset(s) (the original and {len(results)} correction "
            f"set(s)) for {epochs} epochs, starting from {drive.model}")
        drive = replace(drive, model=retrain(drive.model, merged, out / f"model-round{k + 1}.pt", epochs, drive.seed,
                                             drive.device, log))
    return results


def clause_text(clauses: dict) -> str:
    return "; ".join(f"{c} {v['take_overs']} ({v['seconds']:.1f} s)" for c, v in clauses.items()) or "-"


def write_summary(out: Path, results: list[RoundResult], mode: str, complete: bool = True) -> str:
    rows = ["| round | model | rule | autonomy % | corrections [s] | elapsed [s] | take-overs | by clause (take-overs, "
            "seconds) | collisions | while correcting | off path [s] | distance [m] |",
            "|---:|---|---|---:|---:|---:|---:|---|---:|---:|---:|---:|"]
    rows += [f"| {r.round} | {Path(r.model).name} | {r.rule} | {r.autonomy_percent:.2f} | {r.correction_s:.1f} | "
             f"{r.elapsed_s:.1f} | {r.corrections} | {clause_text(r.clauses)} | {r.collisions} | "
             f"{r.collisions_while_correcting} | {r.off_path_s:.1f} | {r.distance_m:.0f} |" for r in results]
    text = f"# Percentage autonomy, {mode} mode\n\n" + "\n".join(rows) + "\n"
    if not complete:
        text += "\n(incomplete: the run was cut off or is still running; more rounds were asked for)\n"
    write_text(out / "autonomy.md", text)
    write_json(out / "autonomy.json", {"mode": mode, "complete": complete, "rounds": [r.row() for r in results]})
    return text


def load_rounds(out: Path) -> list[dict]:
    return json.loads((Path(out) / "autonomy.json").read_text())["rounds"]
