"""Closed-loop data aggregation with exact labels (DAgger: Ross, Gordon and Bagnell, AISTATS 2011) for the
highway's direct perception (docs/aggregation.md).

A network trained on the expert's frames meets, once it drives, states the expert never visits (a car closer
ahead, the host astride a marking, a little off its lane centre); it was never taught to read them. The simulator
knows the exact indicators of every state, so the states a learned driver visits can be labelled for free. Round i
(1..K):

1. **drive**: episodes of generate's highway plan (training tracks only: never a benchmark route) are driven by
   the mixture of the expert and the current model: at every step the expert's command is applied with
   probability beta_i = beta x decay^(i-1), the model's (the Chen controller on its estimates) otherwise; every
   visited frame is recorded with its exact labels, in the dataset format (drivestudio/generate.py's workers);
2. **merge**: the expert dataset (its splits as they were) and every round's frames so far (all training) become
   one dataset (perception/merge.py);
3. **fine-tune**: the model of round i-1 is trained on the merged set (`train --init`), a new optimiser and
   schedule, `iterations` more.

At the end one benchmark drives every round's model (and the oracle) on the held-out suite: each round's score.
Everything is resumable: a round's data, merge and model are each continued or skipped when done
(`aggregation.json` says where the run is), and the same seed gives the same rounds.
"""
from __future__ import annotations

import functools
import json
import os
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np
import torch

from core.files import check_output_dir, make_dir
from core.settings import as_json
from core.worlds.highway import HIGHWAY
from drivestudio.checkpoints import checkpoint_inset, load_predictor_for
from drivestudio.errors import UsageError
from drivestudio.generate import GenerateConfig, generate
from drivestudio.loop import Percept
from drivestudio.outputs import write_json, write_text
from drivestudio.worlds.base import Episode
from drivestudio.worlds.highway.aggregation_config import AggregationConfig
from drivestudio.worlds.highway.benchmark import RunOptions, check_models, load_suite, run_benchmark
from drivestudio.worlds.highway.benchmark.report import write_board
from drivestudio.worlds.highway.benchmark.suite import SUITES_DIR
from drivestudio.worlds.highway.drivers import ChenDriver, reads_behind
from drivestudio.worlds.highway.plugin import Plugin as HighwayPlugin
from perception.checkpoint import load_checkpoint
from perception.merge import Source, merge
from perception.shards import MANIFEST, Dataset, read_manifest
from perception.train import train
from perception.training import TrainConfig
from sim.camera import DEFAULT_RENDERER
from sim.mirror import inset_options

STATE = "aggregation.json"
MADE_BEFORE = {"emphasis": 1}   # a setting's value in runs made before it existed
# settings a run may be continued with another value of: they add rounds, or say how and what to benchmark ("benchmark"
# is the suite's name in runs made before the settings were typed)
ANY_VALUE = ("rounds", "workers", "suite", "benchmark")


# --- driving: the expert and the model, mixed step by step ----------------------------------------------------
class MixedDriver:
    """DAgger's mixture policy: both drivers see every percept (so that each keeps its own state), and the expert's
    command is applied with probability beta, the learner's otherwise. `label` says whose it was."""

    name = "expert+learner"

    def __init__(self, expert, learner, beta: float, seed: int):
        self.expert, self.learner, self.beta = expert, learner, beta
        self.rng = np.random.default_rng([seed, 0xDA6])
        self.label = "expert"
        self.timings: dict[str, float] = {}

    def act(self, percept: Percept) -> tuple[np.ndarray, np.ndarray]:
        expert_action, expert_estimate = self.expert.act(percept)
        if percept.frames[0] is None:   # the warm-up before recording renders nothing: the expert drives it
            self.label = self.expert.label
            return expert_action, expert_estimate
        action, estimate = self.learner.act(percept)
        if self.rng.uniform() < self.beta:
            action, self.label = expert_action, self.expert.label
        else:
            self.label = "learner"
        for driver in (self.expert, self.learner):
            for stage, s in driver.timings.items():
                self.timings[stage] = self.timings.get(stage, 0.0) + s
            driver.timings = dict.fromkeys(driver.timings, 0.0)
        return action, estimate


@functools.cache
def _predictor(path: str, device: str):
    """A worker loads each round's model once, and runs it on one thread (the parallelism is the episodes')."""
    torch.set_num_threads(1)
    return load_predictor_for(path, "highway", device)


class AggregationPlugin(HighwayPlugin):
    """The highway's generation plan, driven by the mixture of its expert and a model (options "learner", "beta",
    "device"); the `perturbation` column says who drove each step ("learner", or the expert's label)."""

    def episode(self, ep: Episode, options: dict, renderer: str):
        world, expert, columns = super().episode(ep, options, renderer)
        predictor = _predictor(options["learner"], options.get("device", "cpu"))
        # the model drives as drive and the benchmark drive it: with the lookout when it estimates the rear labels
        learner = ChenDriver(predictor, lookout=reads_behind(predictor.outputs))
        driver = MixedDriver(expert, learner, float(options["beta"]), ep.seed)

        def labelled(obs) -> dict:
            return {**columns(obs), "perturbation": driver.label}
        return world, driver, labelled


# --- the rounds -------------------------------------------------------------------------------------------------
@functools.cache
def benchmark_tracks() -> frozenset[tuple[str, int]]:
    """(track, lanes) of every route of the shipped suites: aggregation never drives them (read once a process: the
    suites' checks build every route's track)."""
    return frozenset((r.track_ref or r.track, r.lanes) for path in sorted(SUITES_DIR.glob("*.json"))
                     for r in load_suite(path).routes)


def expert_plan(data: str) -> dict:
    """What of the expert dataset's plan the rounds drive too, so that they drive roads and looks like the ones the
    model learned: its lane counts (generate's default 1, 2, 3 for a dataset that does not say), its tracks when it
    named them (else new procedural tracks each round) and its named conditions."""
    options = read_manifest(Path(data)).get("config", {}).get("options", {})
    return {"lanes": [int(n) for n in options.get("lanes", [1, 2, 3])], "tracks": list(options.get("tracks") or []),
            **({"condition": options["condition"]} if options.get("condition") else {})}


def expert_renderer(data: str) -> str:
    """The renderer the rounds draw with and their benchmark drives: the expert dataset's, so that the learner
    meets frames drawn as those it learned from (of a merged dataset's several, the default when it is one of them;
    the default for a dataset that does not say)."""
    named = Dataset(Path(data)).renderers
    return DEFAULT_RENDERER if not named or DEFAULT_RENDERER in named else named[0]


def drive_options(cfg: AggregationConfig, round_: int, learner: Path) -> dict:
    """generate's highway options for a round: the expert dataset's plan (seed cfg.seed * 100 + round, so that every
    round drives new traffic, and new procedural tracks where the expert's were generate's default), denser traffic,
    and the learner, whose frames carry the rear-view mirror (and the side views) when it learned them."""
    plugin = HighwayPlugin()
    seed = cfg.seed * 100 + round_
    plan = expert_plan(cfg.data)
    lanes = plan["lanes"]
    options = {**plan, "procedural": 3, "cars": list(cfg.car_range),
               "width": HIGHWAY.cameras[0].width, "height": HIGHWAY.cameras[0].height, "fov": 60.0,
               **inset_options(checkpoint_inset(str(learner)))}
    held_out = benchmark_tracks()
    tracks = [t for t in plugin.track_list(options, seed) if not any((t, n) in held_out for n in lanes)]
    if not tracks:
        raise UsageError(f"every track of {cfg.data}'s plan is a benchmark route's at one of its lane counts; "
                         "aggregation rounds never drive those")
    return {**options, "tracks": tracks, "learner": str(learner.resolve()), "beta": cfg.beta_of(round_),
            "device": cfg.device}


class Aggregation:
    """One aggregation run in its folder; `run()` does (or continues) every round, then the benchmark."""

    def __init__(self, cfg: AggregationConfig, log=print):
        self.cfg, self.log = cfg, log
        self.workers = cfg.workers or os.cpu_count() or 1
        self.out = make_dir(check_output_dir(cfg.out, "aggregation folder"))
        self.state = self._load_state()

    def _load_state(self) -> dict:
        path = self.out / STATE
        # the cars as the range the rounds drive ([12, 40], as every run has recorded it), whatever its spelling
        config = json.loads(json.dumps(asdict(self.cfg) | {"cars": self.cfg.car_range}))
        if not path.exists():
            return {"config": config, "rounds": [], "complete": False}
        state = json.loads(path.read_text())
        keep = {k: v for k, v in config.items() if k not in ANY_VALUE}
        old = {k: v for k, v in (MADE_BEFORE | state.get("config", {})).items() if k not in ANY_VALUE}
        if old != keep:
            diff = sorted(k for k in set(old) | set(keep) if old.get(k) != keep.get(k))
            raise UsageError(f"{self.out} holds an aggregation run made with other options ({', '.join(diff)} "
                             "differ); give the same options to continue it, or a new --out")
        state["config"] = config
        return state

    def _save(self) -> None:
        write_json(self.out / STATE, self.state)

    def model_of(self, round_: int) -> Path:
        return Path(self.cfg.model) if round_ == 0 else self.out / f"round-{round_}" / "model.pt"

    def run(self) -> dict:
        write_json(self.out / "config.json", as_json(self.cfg))   # `drivestudio aggregate --config` runs it again
        for r in range(1, self.cfg.rounds + 1):
            if r <= len(self.state["rounds"]) and self.state["rounds"][r - 1].get("done"):
                continue
            self.do_round(r)
        if self.cfg.suite != "none":
            self.state["benchmark"] = self.benchmark()
        self.state["complete"] = True
        self._save()
        write_text(self.out / "aggregation.md", report(self.state))
        return self.state

    def do_round(self, r: int) -> None:
        cfg, folder = self.cfg, make_dir(self.out / f"round-{r}")
        t0 = time.perf_counter()
        beta = cfg.beta_of(r)
        self.log(f"round {r} of {cfg.rounds}: driving {cfg.frames} frames, the expert's share {beta:.3f}")
        gen = GenerateConfig(world="highway", frames=cfg.frames, seed=cfg.seed * 100 + r,
                             renderer=expert_renderer(cfg.data), episode_frames=cfg.episode_frames,
                             options=drive_options(cfg, r, self.model_of(r - 1)))
        manifest = generate(folder / "data", gen, workers=self.workers, plugin=AggregationPlugin())
        shares = learner_share(folder / "data")
        merged = folder / "merged"
        if not (merged / MANIFEST).exists():
            merge(merged, [Source(Path(cfg.data))] + [Source(self.out / f"round-{k}" / "data", train_only=True)
                                                       for k in range(1, r + 1)], log=self.log)
        record = self.finetune(r, merged)
        entry = {"round": r, "beta": beta, "frames": manifest["frames"], "learner_share": shares,
                 "merged_frames": Dataset(merged).frames(), "model": str(self.model_of(r)),
                 "val_loss": record.get("val_loss"), "val_mae": record.get("val_mae"),
                 "seconds": round(time.perf_counter() - t0, 1), "done": True}
        self.state["rounds"][r - 1:] = [entry]
        self._save()

    def finetune(self, r: int, merged: Path) -> dict:
        start = load_checkpoint(self.model_of(r - 1), world="highway")
        spec = start["spec"]
        cfg = self.cfg
        train(TrainConfig(data=str(merged), model=spec["name"], out=str(self.model_of(r)),
                          init=str(self.model_of(r - 1)), targets=",".join(spec["labels"]), iterations=cfg.iterations,
                          batch_size=cfg.batch_size, lr=cfg.lr, history=len(spec["input"]["instants"]) - 1,
                          emphasis=cfg.emphasis,
                          device=cfg.device, seed=cfg.seed + r, workers=0), log=self.log)
        history = load_checkpoint(self.model_of(r), world="highway")["train"]["history"]
        last: dict = next((h for h in reversed(history) if h.get("val_loss") is not None), {})
        return {"val_loss": last.get("val_loss"),
                "val_mae": {k[len("val_mae_"):]: v for k, v in last.items() if k.startswith("val_mae_")}}

    def benchmark(self) -> dict:
        suite = load_suite(None if self.cfg.suite == "default" else self.cfg.suite)
        rounds = [str(self.model_of(r)) for r in range(self.cfg.rounds + 1)]
        # a model of the extended labels drives with the lookout: its upper bound is the extended oracle
        exact = ["oracle"] + (["oracle-extended"] if reads_behind(load_checkpoint(rounds[0])["spec"]["outputs"])
                              else [])
        models = check_models(exact + rounds)
        out = make_dir(self.out / "benchmark")
        options = RunOptions(device=self.cfg.device, renderer=expert_renderer(self.cfg.data))
        board = run_benchmark(suite, models, options, out, self.workers)
        write_board(out, board)
        return {"suite": suite.name, "rows": [{"model": e["spec"], **{k: e["overall"][k] for k in
                                               ("driving_score", "score_vs_oracle", "collisions", "off_road_events",
                                                "collisions_per_km", "distance_km")}} for e in board["models"]]}


def learner_share(data: Path) -> float:
    """The share of a round's recorded steps on which the model's command was applied."""
    d = Dataset(data)
    labels = d.labels(None, ["perturbation"])["perturbation"]
    return round(float(np.mean(labels == "learner")), 4) if len(labels) else 0.0


def report(state: dict) -> str:
    """aggregation.md: one row per round, then the benchmark's rows."""
    rows = ["# Data aggregation", "", "| round | expert share | frames | learner drove | merged frames | val loss | "
            "minutes |", "|---:|---:|---:|---:|---:|---:|---:|"]
    for r in state["rounds"]:
        loss = f"{r['val_loss']:.4f}" if r.get("val_loss") is not None else "-"
        rows.append(f"| {r['round']} | {r['beta']:.3f} | {r['frames']} | {r['learner_share']:.1%} | "
                    f"{r['merged_frames']} | {loss} | {r['seconds'] / 60:.1f} |")
    bench = state.get("benchmark")
    if bench:
        rows += ["", f"## Benchmark, suite '{bench['suite']}'", "", "| model | driving score | vs oracle | "
                 "collisions | collisions/100 km | off-road | km |", "|---|---:|---:|---:|---:|---:|---:|"]
        for b in bench["rows"]:
            rows.append(f"| {b['model']} | {b['driving_score']:.1%} | {b['score_vs_oracle']:.1%} | {b['collisions']} | "
                        f"{b['collisions_per_km'] * 100:.1f} | {b['off_road_events']} | {b['distance_km']:.1f} |")
    return "\n".join(rows) + "\n"
