"""Percentage autonomy (Chowdhuri, Pankaj and Zipser, MultiNet, 2017): a trained network drives a held-out sidewalk
loop with obstacles while the expert watches under the correction rule (controller/sidewalk/correction.py);
autonomy = (1 - correction time / elapsed time) * 100.

Every step of the run is recorded into a dataset (the same format as `generate`'s) with its operation mode, so the
expert's corrections can be merged into the training data: the paper's DAgger variant, which needs no labelling
after the fact. MultiNet's trainer learns only from moments whose targets the expert drove (autonomous steps are
the network's own commands, not labels). `rounds` repeats drive, merge and retrain.
"""
from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from types import SimpleNamespace

HELD_OUT_PATH = "procedural:907"   # a winding 214 m park loop that generate's default plan never drives
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
    dataset: str
    video: str | None

    def row(self) -> dict:
        return dict(self.__dict__)


def drive_round(model: str, mode: str, seconds: float, out: Path, k: int, path: str = HELD_OUT_PATH,
                obstacles=HELD_OUT_OBSTACLES, seed: int = 0, video: bool = True, device: str = "cpu",
                log=print) -> RoundResult:
    """One autonomy run: the model drives, the expert corrects; the run's steps become dataset out/corrections-k."""

    from drivestudio import worlds
    from drivestudio.bridge_loop import supervised
    from drivestudio.generate import _software
    from drivestudio.loop import in_process, run_loop
    from perception.shards import SPLIT_RULE, ShardInfo, ShardWriter, shard_name, write_manifest

    plugin = worlds.get("sidewalk")
    args = SimpleNamespace(path=path, path_width=None, seed=seed, mode=mode, obstacles=str(obstacles), width=None,
                           height=None, fov=None, renderer="tiny", operation="correctional", model=model,
                           device=device)
    data_dir = out / f"corrections-{k}"
    with plugin.world(args, render=True) as world:
        decl = world.declaration
        driver = plugin.driver(model, args, decl)
        driver.mode = mode   # the network is told its behavioural mode, as the car's operator sets it
        metrics = plugin.metrics(world)
        video_path = out / f"autonomy-{k}.mp4" if video else None
        recorder = plugin.recorder(world, video_path, f"{Path(model).stem} ({mode})")
        writer = ShardWriter(data_dir / shard_name(0), decl)

        def on_step(rec) -> None:
            recorder(rec)
            obs = rec.obs
            writer.add(obs.frames, obs.record, {"path": path}, episode=0, step=len(writer), t=obs.t, seed=seed,
                       action=rec.action)

        ok = False
        t0 = time.perf_counter()
        try:
            run_loop(world, supervised(in_process(driver), plugin.supervisor(world, args)), seconds, render=True,
                     metrics=metrics, on_step=on_step, when_lost="recover")
            ok = True
        finally:
            recorder.close(ok)
        report = metrics.report()
    written = writer.close()
    entry = ShardInfo(shard_name(0), 0, written["frames"], "train", {"path": path, "mode": mode,
                                                                       "operation": "correctional"},
                      written["size"], written["sha256"]).entry()
    write_manifest(data_dir, {"world": decl.to_json(), "config": {"world": "sidewalk", "autonomy": {
        "model": str(model), "mode": mode, "path": path, "obstacles": obstacles, "seconds": seconds, "seed": seed}},
        "seed": seed, "renderer": "tiny", "split_rule": SPLIT_RULE, "software": _software(),
        "created": time.strftime("%Y-%m-%dT%H:%M:%S%z"), "shards": [entry], "frames": written["frames"],
        "complete": True})
    elapsed = metrics.steps * world.dt                 # exact: the report's seconds are rounded for reading
    correction = metrics.correction_steps * world.dt
    result = RoundResult(k, str(model), round(percentage_autonomy(correction, elapsed), 2), round(correction, 3),
                         round(elapsed, 3),
                         int(report.get("corrections", 0)), int(report["collisions"]),
                         float(report["off_path_time_s"]), float(report["distance_m"]), str(data_dir),
                         str(video_path) if video_path else None)
    log(f"round {k}: autonomy {result.autonomy_percent:.2f} % ({correction:.1f} s of corrections in {elapsed:.1f} s, "
        f"{result.corrections} take-overs, {result.collisions} collisions) in {time.perf_counter() - t0:.0f} s; "
        f"steps recorded in {data_dir}")
    return result


def run(model: str, mode: str, seconds: float, out: Path, rounds: int = 1, epochs: int = 3, data: str | None = None,
        path: str = HELD_OUT_PATH, obstacles=HELD_OUT_OBSTACLES, seed: int = 0, device: str = "cpu",
        video: bool = True, log=print) -> list[RoundResult]:
    """`rounds` rounds of drive, merge the corrections, retrain (fine-tuning the last model for `epochs` epochs on
    the original data plus every round's corrections); returns the autonomy of every round."""
    from perception.checkpoint import load_checkpoint
    from perception.train import train
    from perception.training import config_from

    results: list[RoundResult] = []
    current = str(model)
    spec = load_checkpoint(current, world="sidewalk")
    roots = [r for r in (data or ",".join(spec.get("data", {}).get("roots", []))).split(",") if r]
    for k in range(rounds):
        results.append(drive_round(current, mode, seconds, out, k, path, obstacles, seed, video, device, log))
        write_summary(out, results, mode)
        if k + 1 == rounds:
            break
        if not roots:
            from drivestudio.errors import UsageError
            raise UsageError("--rounds needs the training data: give --data (the checkpoint does not record it)")
        merged = roots + [r.dataset for r in results]
        nxt = out / f"model-round{k + 1}.pt"
        options = spec["spec"]["options"]
        log(f"round {k + 1}: retraining on {len(merged)} dataset(s) (the original and {len(results)} correction "
            f"set(s)) for {epochs} epochs, starting from {current}")
        train(config_from(data=",".join(merged), model="z2color", out=str(nxt), epochs=epochs, trials=1, seed=seed,
                          device=device, init=current, mtl=options.get("mtl"),
                          modes=None if options.get("mtl") else ",".join(options.get("modes_trained", []))
                          or None), log=log)
        current = str(nxt)
    return results


def write_summary(out: Path, results: list[RoundResult], mode: str) -> str:
    from drivestudio.outputs import write_json, write_text
    rows = ["| round | model | autonomy % | corrections [s] | elapsed [s] | take-overs | collisions | off path [s] | "
            "distance [m] |", "|---:|---|---:|---:|---:|---:|---:|---:|---:|"]
    rows += [f"| {r.round} | {Path(r.model).name} | {r.autonomy_percent:.2f} | {r.correction_s:.1f} | "
             f"{r.elapsed_s:.1f} | {r.corrections} | {r.collisions} | {r.off_path_s:.1f} | {r.distance_m:.0f} |"
             for r in results]
    text = f"# Percentage autonomy, {mode} mode\n\n" + "\n".join(rows) + "\n"
    write_text(out / "autonomy.md", text)
    write_json(out / "autonomy.json", {"mode": mode, "rounds": [r.row() for r in results]})
    return text


def load_rounds(out: Path) -> list[dict]:
    return json.loads((Path(out) / "autonomy.json").read_text())["rounds"]
