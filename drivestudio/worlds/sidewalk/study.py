"""The MultiNet study in one command (Chowdhuri, Pankaj and Zipser, MultiNet, 2017, sections 2.4 and 4.2-4.4, in
simulation): `drivestudio study --out DIR`.

1. **Data**: a balanced data-moment set of the sidewalk world: the three behavioural modes in equal episodes over the
   presets and `procedural` procedural loops, every episode with its own look (time of day, colours, obstacles).
2. **Training**: MultiNet (Z2Color with modal insertion) on all of it, and three MTL nets (no modal input), each on
   one mode's data, `trials` times each with fresh seeds, validated every epoch on the last step (equation 2).
3. **Figures 7 and 8**: MultiNet's validation loss against the mean of the three MTL nets', and in furtive mode
   against the furtive MTL net, means over trials with 95 % confidence intervals.
4. **Correction rounds** (the paper's DAgger variant, section 2.4): each network evaluated below (MultiNet, the direct
   and the furtive MTL nets) drives training loops in its modes under the expert's correction; the corrections are
   merged with the data and the network is fine-tuned on both, `rounds` times.
5. **Percentage autonomy** (section 4.4) in direct and furtive mode, MultiNet against the MTL net of that mode, on the
   held-out loops (never driven by the data or the rounds), `runs` runs of `autonomy_seconds` per loop, under both
   correction rules (the study's `rule` first); mean and 95 % confidence interval over the runs; take-overs by the
   clause that caused them; collisions while the expert held the wheel.
   The data, the rounds and these runs are drawn in the study's `condition` (docs/conditions.md; a mix: each
   episode or run draws one); with `new_conditions`, the runs of the study's rule are repeated under each held-out
   condition on its own, and the report sets MultiNet against MTL there beside the training conditions.
6. **STUDY.md** and **study.json**: the tables beside the paper's numbers, the sizes of the networks, the data and
   the times.

Every step goes through the verbs a user runs (generate, train, autonomy), each a process of the pool
(drivestudio/pool.py; `--backend ray`: Ray tasks), and skips what is done, so a study that
was cut off continues where it stopped when the same command runs again.
"""
from __future__ import annotations

import json
import math
import os
import resource
import time
from dataclasses import asdict, dataclass
from pathlib import Path

from controller.sidewalk.correction import RULES
from core.conditions import CONDITIONS, SEEDED, names
from core.settings import MAX_SEED, as_json, setting
from drivestudio.errors import RunError, UsageError
from drivestudio.pool import Job, JobFailed, Pool, run_verb
from drivestudio.worlds.sidewalk.autonomy import HELD_OUT_PATHS
from drivestudio.worlds.sidewalk.study_report import EVALUATED, MODES, write_report
from perception.train_outputs import check_train_outputs

ROUND_LOOPS = ("park", "sidewalk", "forest")         # training loops the correction rounds drive
MOMENT_MARGIN = 11     # steps of an episode that start no moment: the one before the first, the ten after the last
# settings that shape what a study has made (its data, its trained networks, its rounds' recordings): a study is
# continued only with the same (and the same length of autonomy runs, which are kept); the others (more
# rounds, other loops, more runs) only add or measure anew
SHAPING = ("moments", "episode_frames", "procedural", "perturbed", "epochs", "trials", "batch_size", "steer_share",
           "round_seconds", "round_epochs", "round_moments", "rule", "seed", "autonomy_seconds", "condition")
# a setting's value in studies made before it existed
MADE_BEFORE = {"round_moments": 0, "perturbed": 0.0, "steer_share": 0.0, "condition": SEEDED}
NAMED = tuple(c for c in CONDITIONS if c != SEEDED)   # the conditions a study can hold out
NEW_STAGE = "new-conditions"   # the folder of the final runs under the held-out conditions


@dataclass(frozen=True)
class StudyConfig:
    out: str = setting("out/study", "folder of the study")
    # the data: short episodes over many loops, more paths for the same steps
    moments: int = setting(30_000, "data moments at least", low=100, high=10**8)
    episode_frames: int = setting(125, "steps per episode", low=20, high=10**5)
    # the plan's 264 episodes of three modes per loop reach the first 85 of the 120 loops
    procedural: int = setting(120, "procedural loops beside the presets", low=0, high=1000)
    perturbed: float = setting(0.5, "share of the data's episodes whose expert is knocked aside now and then, its "
                                    "recoveries labelled (docs/sidewalk.md)", low=0.0, high=1.0)
    # the trainings
    epochs: int = setting(5, "epochs per trial", low=1, high=1000)
    trials: int = setting(3, "trials per network", low=1, high=100)
    batch_size: int = setting(120, "moments per batch", low=3, high=65536)
    steer_share: float = setting(0.0, "share of each mode's draws from its steering moments in every training (train's "
                                      "steer_share)", low=0.0, high=1.0)
    # the correction rounds before the final autonomy runs
    rounds: int = setting(6, "correction rounds before the final autonomy runs", low=1, high=20)
    round_seconds: float = setting(150.0, "simulated seconds each network drives per mode and round", unit="s",
                                   low=0.1, high=24 * 3600.0)
    round_epochs: int = setting(2, "fine-tuning epochs per round", low=1, high=1000)
    # a fixed cost per round (not a growing set) is what lets six rounds fit in the 2.5 hours
    round_moments: int = setting(2500, "moments of each mode an epoch of a round's fine-tuning draws from the data and "
                                       "every round's recordings, 0 for all of them", low=0, high=10**9)
    # the autonomy runs (seeds 100, 101, ... per loop)
    loops: str = setting(",".join(HELD_OUT_PATHS), "held-out loops of the autonomy runs, comma-separated")
    runs: int = setting(3, "autonomy runs per loop", low=1, high=1000)
    autonomy_seconds: float = setting(60.0, "simulated seconds per autonomy run", unit="s", low=0.1, high=24 * 3600.0)
    baseline_runs: int = setting(0, "autonomy runs per loop before the rounds, under the study's rule, 0 for none",
                                 low=0, high=1000)
    rule: str = setting("safety", "the correction rule of the rounds and the headline; the final runs measure both",
                        choices=RULES)
    # the look (docs/conditions.md): what the networks learn from and are corrected in, and what they never saw
    condition: str = setting(SEEDED, "the named conditions of the data, the correction rounds and the final autonomy "
                                     "runs: one, or a mix each episode and run draws one of",
                             choices=CONDITIONS, several=True)
    new_conditions: str | None = setting(None, "held-out conditions the final runs of the study's rule are repeated "
                                               "in, each on its own (none: no such runs)", choices=NAMED,
                                         several=True)
    device: str = setting("cpu", "torch device: cpu, cuda, cuda:N or auto (cuda: the paper's epochs and trials)")
    seed: int = setting(0, "seed of the data, the trials and the runs", low=0, high=MAX_SEED)
    jobs: int = setting(2, "trainings and autonomy runs side by side, each with cores / jobs threads", low=1, high=64)

    @property
    def loop_names(self) -> tuple[str, ...]:
        return tuple(p.strip() for p in self.loops.split(",") if p.strip())

    @property
    def new_condition_names(self) -> tuple[str, ...]:
        return names(self.new_conditions) if self.new_conditions else ()

    @property
    def frames(self) -> int:
        """Steps to record: whole episodes, a multiple of the three modes, holding at least `moments` moments."""
        episodes = math.ceil(self.moments / (self.episode_frames - MOMENT_MARGIN))
        return (-(-episodes // len(MODES)) * len(MODES)) * self.episode_frames

    @property
    def rules(self) -> tuple[str, ...]:
        return (self.rule,) + tuple(r for r in RULES if r != self.rule)


QUICK: dict = dict(moments=240, episode_frames=40, procedural=0, epochs=2, trials=2, batch_size=30, rounds=2,
             round_seconds=2.0, round_epochs=1, round_moments=0, runs=1, autonomy_seconds=2.0, baseline_runs=0)
PAPER_SCALE: dict = dict(moments=200_000, epochs=24, trials=8, rounds=2, round_seconds=300.0, round_moments=0,
                   runs=5, autonomy_seconds=180.0, baseline_runs=1)   # --device cuda: the paper's epochs and trials


def run_jobs(jobs: list[Job], parallel: int, logs: Path, command: tuple | None = None, backend: str = "local") \
        -> None:
    """Verbs as processes of the pool (drivestudio/pool.py), `parallel` at a time, each with cores / parallel torch
    threads: one thread per process wastes no time in the threads' barriers when the cores are shared (measured on
    this machine under load: 180 training moments per CPU-second with one thread, 40-60 with two). A free slot takes
    the first job in the list whose `after` jobs have finished, so one network's drives fill the time another spends
    retraining. A failure ends the study (exit status 1) once the running ones are done; Ctrl-C or SIGTERM ends them
    (each verb keeps what it finished). With backend "ray" every job that may start is a Ray task (one CPU), and the
    cluster decides how many run at once; `logs` and the study's folder must then be paths every node shares."""
    env = {"OMP_NUM_THREADS": str(max(1, (os.cpu_count() or 1) // parallel))} if backend == "local" else {}
    logs.mkdir(parents=True, exist_ok=True)
    for job in jobs:
        job.log = logs / f"{job.name}.log"

    def started(job: Job) -> None:
        print("$ drivestudio " + " ".join(map(str, job.argv or [])) + f"   (log: {job.log})", flush=True)

    try:
        Pool(backend, slots=parallel, env=env, finish=True, command=command).run(jobs, on_start=started)
    except JobFailed as e:
        raise RunError(f"{', '.join(j.name for j in e.jobs)} failed: see {logs}/{e.jobs[0].name}.log") from None


class Study:
    def __init__(self, cfg: StudyConfig, backend: str = "local"):
        self.cfg = cfg
        self.backend = backend   # of the pool that runs the verbs: local processes or Ray tasks
        self.out = Path(cfg.out)
        self.data, self.models, self.logs = self.out / "data", self.out / "models", self.out / "logs"
        self.times_path = self.out / "times.json"
        # per stage, over every run of the command (a study cut off and continued adds up): wall and CPU seconds
        self.timings: dict[str, dict[str, float]] = \
            json.loads(self.times_path.read_text()) if self.times_path.exists() else {}

    def timed(self, name: str, fn, *args):
        def cpu() -> float:   # this process and every finished process it started (verbs, their workers)
            me, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
            return me.ru_utime + me.ru_stime + children.ru_utime + children.ru_stime

        t, c = time.perf_counter(), cpu()
        try:
            return fn(*args)
        finally:
            slot = self.timings.setdefault(name, {"wall_s": 0.0, "cpu_s": 0.0})
            slot["wall_s"] = round(slot["wall_s"] + time.perf_counter() - t, 1)
            slot["cpu_s"] = round(slot["cpu_s"] + cpu() - c, 1)
            self.times_path.write_text(json.dumps(self.timings, indent=1) + "\n")

    def check_continuation(self) -> None:
        """A study found in --out is continued only with the settings that made it (UsageError otherwise, before
        anything is written): a checkpoint trained for 10 epochs must not pass for one of 12."""
        path = self.out / "config.json"
        if not path.exists():
            return
        try:
            made = json.loads(path.read_text())
        except (OSError, ValueError) as e:
            raise UsageError(f"--out {self.out}: its config.json is unreadable ({e}); give another folder") from None
        if not isinstance(made, dict):
            raise UsageError(f"--out {self.out}: its config.json is not a study's settings; give another folder")
        asked = asdict(self.cfg)
        differ = [f"{k}={made.get(k, MADE_BEFORE.get(k))!r} (asked {asked[k]!r})" for k in SHAPING
                  if made.get(k, MADE_BEFORE.get(k)) != asked[k]]
        if differ:
            raise UsageError(f"--out {self.out} holds a study made with {', '.join(differ)}; continue it with the "
                             "same settings or give another folder")

    def check_outputs(self) -> None:
        """Every network the study trains, with the files its training writes beside it, checked before the data
        is recorded (OutputError): a folder in the place of a curve would otherwise end the study hours in."""
        names = list(self.nets()) + [f"{name}-round{k}" for k in range(1, self.cfg.rounds + 1)
                                     for name in ("multinet", "mtl-direct", "mtl-furtive")]
        for name in names:
            check_train_outputs(self.models / f"{name}.pt", "multinet")

    def jobs(self, stage: str, jobs: list[Job]) -> None:
        if jobs:
            self.timed(stage, run_jobs, jobs, self.cfg.jobs, self.logs, None, self.backend)

    # --- 1. data ---------------------------------------------------------------------------------------------------
    def generate(self) -> None:
        manifest = self.data / "manifest.json"
        if manifest.exists() and json.loads(manifest.read_text()).get("complete"):
            return
        c = self.cfg
        self.timed("generate", self.verb, "generate", "--world", "sidewalk", "--out", self.data, "--frames", c.frames,
                   "--episode-frames", c.episode_frames, "--procedural", c.procedural, "--seed", c.seed,
                   *(["--perturbed", c.perturbed] if c.perturbed else []),
                   *(["--set", f"condition={c.condition}"] if c.condition != SEEDED else []),
                   *(["--backend", "ray"] if self.backend == "ray" else []))

    def verb(self, *argv) -> None:
        """A verb as a process of its own, its output this one's; its failure (its one line already on stderr)
        ends the study with its exit status."""
        print("$ drivestudio " + " ".join(map(str, argv)), flush=True)
        run_verb(list(argv))

    def cache(self) -> None:
        """The moments cached at 94 x 168 once, before the trainings that share them start together."""
        from perception.moments import Moments  # lazy: torch, pyarrow
        self.timed("cache", Moments, [self.data], (94, 168))

    # --- 2. training -------------------------------------------------------------------------------------------------
    def nets(self) -> dict[str, list[str]]:
        return {"multinet": []} | {f"mtl-{m}": ["--set", f"mtl={m}"] for m in MODES}

    def draws(self) -> list:
        """The trainings' options beyond the plain balanced draw."""
        return ["--set", f"steer_share={self.cfg.steer_share}"] if self.cfg.steer_share else []

    def trained(self, ckpt: Path) -> bool:
        return ckpt.exists() and not Path(str(ckpt) + ".state").exists()

    def train(self) -> None:
        c = self.cfg
        self.jobs("train", [Job(f"train-{name}", ["train", "--data", self.data, "--model", "z2color", "--out",
                                                  self.models / f"{name}.pt", *extra, "--epochs", c.epochs, "--set",
                                                  f"trials={c.trials}", "--batch-size", c.batch_size, "--seed", c.seed,
                                                  *self.draws(), "--device", c.device])
                            for name, extra in self.nets().items() if not self.trained(self.models / f"{name}.pt")])

    # --- 4. correction rounds ----------------------------------------------------------------------------------------
    def net_modes(self, name: str) -> tuple[str, ...]:
        return MODES if name == "multinet" else (name.removeprefix("mtl-"),)

    def round_dir(self, k: int, name: str, mode: str) -> Path:
        return self.out / "rounds" / f"round{k}" / f"{name}-{mode}"

    @staticmethod
    def retrain_name(k: int, name: str) -> str:
        return f"round{k}-retrain-{name}"

    def correction_rounds(self, names) -> tuple[dict[str, str], list[Job]]:
        """The networks after the correction rounds and the jobs that make them: each round every network drives a
        training loop in each of its modes under the expert's correction, then is fine-tuned on the data and every
        correction of its own so far. A network's round waits only for its own previous one."""
        c = self.cfg
        current = {name: str(self.models / f"{name}.pt") for name in names}
        jobs: list[Job] = []
        for k in range(1, c.rounds + 1):
            for name in names:
                before: tuple[str, ...] = (self.retrain_name(k - 1, name),) if k > 1 else ()
                planned = [self.drive_job(f"round{k}-{name}-{mode}", current[name], mode,
                                          ROUND_LOOPS[(k - 1 + i) % len(ROUND_LOOPS)], c.seed + k, c.round_seconds,
                                          c.rule, self.round_dir(k, name, mode), after=before,
                                          condition=c.condition, record=True)
                           for i, mode in enumerate(self.net_modes(name))]
                drives = [j for j in planned if j is not None]   # a drive whose result exists is done
                jobs += drives
                nxt = self.models / f"{name}-round{k}.pt"
                roots = [self.data] + [self.round_dir(j, name, m) / "corrections-0" for j in range(1, k + 1)
                                       for m in self.net_modes(name)]
                kind = ["--set", f"mtl={name.removeprefix('mtl-')}"] if name.startswith("mtl-") else []
                if not self.trained(nxt):
                    jobs.append(Job(self.retrain_name(k, name), [
                        "train", "--data", ",".join(map(str, roots)), "--model", "z2color", "--out", nxt, *kind,
                        "--epochs", c.round_epochs, "--set", "trials=1", "--batch-size", c.batch_size, "--seed",
                        c.seed + k, *(["--set", f"mode_moments={c.round_moments}"] if c.round_moments else []),
                        *self.draws(),
                        "--device", c.device, "--init", current[name]], before + tuple(j.name for j in drives)))
                current[name] = str(nxt)
        return current, jobs

    # --- 5. autonomy ---------------------------------------------------------------------------------------------
    def drive_job(self, name: str, model: str, mode: str, loop: str, seed: int, seconds: float, rule: str,
                  where: Path, video: bool = False, after: tuple = (), condition: str = SEEDED,
                  record: bool = False) -> Job | None:
        """An autonomy run as a job (None when its result exists): the round-0 result of `drivestudio autonomy`;
        `record`: its steps kept as a dataset (a correction round's, which its retraining merges)."""
        if (where / "autonomy.json").exists():
            return None
        return Job(name, ["autonomy", "--model", model, "--mode", mode, "--path", loop, "--set", f"seed={seed}",
                          "--seconds", seconds, "--rule", rule, "--device", self.cfg.device, "--out", where,
                          *([] if video else ["--set", "video=false"]), *([] if record else ["--set", "record=false"]),
                          *(["--set", f"condition={condition}"] if condition != SEEDED else [])], after)

    def autonomy_plan(self, stage: str, nets: dict[str, str], rules, runs: int, last_round: int,
                      held_out: str | None = None) -> list[tuple]:
        """(rule, mode, network title, result folder, job or None) of every autonomy run of a stage, in the study's
        conditions or, given `held_out`, in that one (in a folder of its own); a run after the rounds waits for its
        own network's `last_round` only."""
        c = self.cfg
        root, tag = (self.out / stage / held_out, f"{stage}-{held_out}") if held_out else (self.out / stage, stage)
        plan = []
        for rule in rules:
            for mode in EVALUATED:
                for title, name in (("MultiNet", "multinet"), ("MTL", f"mtl-{mode}")):
                    for loop in c.loop_names:
                        for r in range(runs):
                            # under the model's own name: after more rounds, the newer networks are measured anew
                            where = root / rule / mode / Path(nets[name]).stem / f"{loop.replace(':', '-')}-{100 + r}"
                            video = rule == c.rule and loop == c.loop_names[0] and r == 0
                            plan.append((rule, mode, title, where, self.drive_job(
                                f"{tag}-{rule}-{mode}-{name}-{where.name}", nets[name], mode, loop, 100 + r,
                                c.autonomy_seconds, rule, where, video,
                                after=(self.retrain_name(last_round, name),) if last_round else (),
                                condition=held_out or c.condition)))
        return plan

    def new_conditions_plan(self, nets: dict[str, str]) -> dict[str, list[tuple]]:
        """{held-out condition: its plan}: the final runs of the study's rule again, in each new condition."""
        c = self.cfg
        return {name: self.autonomy_plan(NEW_STAGE, nets, (c.rule,), c.runs, c.rounds, name)
                for name in c.new_condition_names}

    @staticmethod
    def autonomy_results(plan: list[tuple]) -> dict:
        """{rule: {mode: {"MultiNet"|"MTL": [run results]}}} over every loop and run of a plan that has run."""
        out: dict = {}
        for rule, mode, title, where, _ in plan:
            result = json.loads((where / "autonomy.json").read_text())["rounds"][0]
            out.setdefault(rule, {}).setdefault(mode, {}).setdefault(title, []).append(result)
        return out

    # --- the whole ------------------------------------------------------------------------------------------------
    def run(self) -> Path:
        t0 = time.perf_counter()
        self.check_continuation()
        self.check_outputs()
        self.out.mkdir(parents=True, exist_ok=True)
        # what the continuation is held to, and what `drivestudio study --config` runs again
        (self.out / "config.json").write_text(json.dumps(as_json(self.cfg), indent=1) + "\n")
        self.generate()
        self.cache()
        self.train()
        first = {name: str(self.models / f"{name}.pt") for name in self.nets()}
        final, rounds = self.correction_rounds(("multinet", "mtl-direct", "mtl-furtive"))
        baseline = self.autonomy_plan("baseline", first, (self.cfg.rule,), self.cfg.baseline_runs, 0)
        autonomy = self.autonomy_plan("autonomy", final, self.cfg.rules, self.cfg.runs, self.cfg.rounds)
        new = self.new_conditions_plan(final)
        # one pool: the rounds first (the longest chain), the baseline runs filling its gaps, each final run as soon
        # as its network's last round is done
        runs = baseline + autonomy + [p for plan in new.values() for p in plan]
        self.jobs("rounds and autonomy", rounds + [job for *_, job in runs if job is not None])
        held_out = {name: self.autonomy_results(plan)[self.cfg.rule] for name, plan in new.items()}
        return write_report(self, self.autonomy_results(baseline), self.autonomy_results(autonomy), final,
                            time.perf_counter() - t0, held_out)


