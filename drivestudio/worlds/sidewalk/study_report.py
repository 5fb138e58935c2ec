"""The MultiNet study's report (drivestudio/worlds/sidewalk/study.py): Figures 7 and 8, STUDY.md and study.json with
the validation curves, the correction rounds, percentage autonomy by rule, mode and network beside the paper's
numbers and, with held-out conditions, under them beside the training conditions, the networks' sizes, the data and
the times."""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from core.conditions import SEEDED
from drivestudio.outputs import write_json, write_text
from drivestudio.worlds.sidewalk.autonomy import clause_text

MODES = ("direct", "follow", "furtive")
EVALUATED = ("direct", "furtive")                   # follow mode is excluded from the autonomy test, as in the paper
PAPER: dict[str, Any] = {
    "autonomy": {"direct": {"MultiNet": 92.68, "MTL": 84.27}, "furtive": {"MultiNet": 88.23, "MTL": 87.55}},
    "parameters": "no more than 1.7 M (about 6.5 MB)", "moments": 1_930_000, "epochs": 24, "trials": 8,
    "correctional_share": 0.1924}


def mean_ci(values) -> tuple[float, float | None]:
    """Mean and 95 % confidence half-width (Student's t) of some runs' values."""
    from perception.multinet import t95  # lazy: torch
    v = np.asarray(values, dtype=np.float64)
    if len(v) < 2:
        return float(v.mean()), None
    return float(v.mean()), float(t95(len(v) - 1) * v.std(ddof=1) / math.sqrt(len(v)))


# what the paper's curves do (its section 4.2 and 4.3), written beside our figures
PAPER_FIGURE7 = ("the paper's Figure 7 (24 epochs, 8 trials): MultiNet slightly above the MTL mean in epochs "
                 "1-4, level or below in 4-10, far below in 10-17 while the MTL nets flatten and wander between "
                 "local minima, and the MTL nets overfitting in 17-24 while MultiNet keeps falling")
PAPER_FIGURE8 = ("the paper's Figure 8 (furtive mode): level in epochs 1-4, MultiNet falling steadily in 4-10 "
                 "while the furtive MTL net oscillates, the MTL net overfitting from epoch 10 while MultiNet keeps "
                 "learning")


def summary(ckpt: Path) -> list[dict]:
    """Per epoch: means over trials and 95 % half-widths of a training (its checkpoint's record)."""
    from perception.checkpoint import load_checkpoint  # lazy: torch
    return load_checkpoint(ckpt)["train"]["summary"]


def figure(path: Path, multi: list[dict], mtl: list[list[dict]], key: str, title: str) -> Path:
    """Validation loss per epoch with 95 % confidence bands: MultiNet (`key` of its summary) against an MTL net,
    or the mean of several (their bands combined as for a mean of independent means)."""
    import matplotlib  # lazy: matplotlib, only when a figure is drawn
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # lazy: as above
    from matplotlib.ticker import MaxNLocator  # lazy: as above

    fig, ax = plt.subplots(figsize=(7, 4), dpi=110)
    x = [r["epoch"] for r in multi]
    m = np.array([r[f"{key}_mean"] for r in multi])
    c = np.array([r.get(f"{key}_ci95") or 0.0 for r in multi])
    ax.plot(x, m, "o-", color="C0", label="MultiNet", markersize=3)
    ax.fill_between(x, m - c, m + c, color="C0", alpha=0.2)
    mean = np.mean([[r["val_loss_mean"] for r in net] for net in mtl], axis=0)
    ci = np.sqrt(np.sum([[(r.get("val_loss_ci95") or 0.0) ** 2 for r in net] for net in mtl], axis=0)) / len(mtl)
    ax.plot(x, mean, "s--", color="C3", label="MTL" if len(mtl) == 1 else f"MTL (mean of {len(mtl)} nets)",
            markersize=3)
    ax.fill_between(x, mean - ci, mean + ci, color="C3", alpha=0.2)
    ax.set_xlabel("epoch")
    ax.set_ylabel("validation loss, last step (eq. 2)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend()
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def figures(out: Path, multi: list[dict], mtl: dict) -> tuple[Path, Path]:
    f7 = figure(out / "figure7-all-modes.png", multi, [mtl[m] for m in MODES], "val_loss",
                "All modes: MultiNet vs the mean of the three MTL nets (the paper's Figure 7)")
    f8 = figure(out / "figure8-furtive.png", multi, [mtl["furtive"]], "val_loss_furtive",
                "Furtive mode: MultiNet vs the furtive MTL net (the paper's Figure 8)")
    return f7, f8


def verdicts(multi: list[dict], mtl: dict) -> dict:
    """From mid-training on (the second half of the epochs): in how many epochs MultiNet's mean validation loss is at
    or below the MTL nets' mean (Figure 7), and on furtive moments at or below the furtive MTL net's (Figure 8)."""
    n = len(multi)
    later = range(n // 2, n)
    mtl_mean = [np.mean([mtl[m][i]["val_loss_mean"] for m in MODES]) for i in range(n)]
    fig7 = sum(bool(multi[i]["val_loss_mean"] <= mtl_mean[i]) for i in later)
    fig8 = sum(bool(multi[i]["val_loss_furtive_mean"] <= mtl["furtive"][i]["val_loss_mean"]) for i in later)
    return {"figure7": [int(fig7), len(later)], "figure8": [int(fig8), len(later)]}


def corrected_moments(root: Path) -> tuple[int, int]:
    """(steps the expert corrected, data moments they add to training) of one recorded autonomy run."""
    from perception.shards import Dataset  # lazy: pyarrow
    labels = Dataset(root).labels(columns=("operation", "correcting"))
    expert = labels["operation"] != 1
    starts = range(1, len(expert) - 10)
    return int(labels["correcting"].sum()), sum(bool(expert[t + 1:t + 11].all()) for t in starts)


def folder_mb(path: Path) -> float:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file()) / 1e6


def _fmt(r: dict, key: str) -> str:
    v, c = r.get(f"{key}_mean"), r.get(f"{key}_ci95")
    return "-" if v is None else f"{v:.4f}" + (f" ± {c:.4f}" if c else "")


def validation_table(multi: list[dict], mtl: dict) -> str:
    rows = ["| epoch | MultiNet (all modes) | MTL mean of 3 | MTL direct | MTL follow | MTL furtive | MultiNet, "
            "furtive moments |", "|---:|---:|---:|---:|---:|---:|---:|"]
    for i, r in enumerate(multi):
        mean = np.mean([mtl[m][i]["val_loss_mean"] for m in MODES])
        rows.append(f"| {int(r['epoch'])} | {_fmt(r, 'val_loss')} | {mean:.4f} | "
                    + " | ".join(_fmt(mtl[m][i], "val_loss") for m in MODES) + f" | {_fmt(r, 'val_loss_furtive')} |")
    return "\n".join(rows)


def autonomy_row(results: list[dict]) -> dict:
    """Mean and 95 % interval of a network's autonomy over its runs, and the sums of what the runs counted."""
    mean, ci = mean_ci([r["autonomy_percent"] for r in results])
    clauses: dict = {}
    for r in results:
        for c, v in r.get("clauses", {}).items():
            slot = clauses.setdefault(c, {"take_overs": 0, "seconds": 0.0})
            slot["take_overs"] += v["take_overs"]
            slot["seconds"] = round(slot["seconds"] + v["seconds"], 3)
    return {"runs": len(results), "autonomy_mean": round(mean, 2),
            "autonomy_ci95": None if ci is None else round(ci, 2),
            "autonomy_runs": [r["autonomy_percent"] for r in results],
            "take_overs": sum(r["corrections"] for r in results), "clauses": clauses,
            "collisions": sum(r["collisions"] for r in results),
            "collisions_while_correcting": sum(r.get("collisions_while_correcting", 0) for r in results),
            "distance_m": round(sum(r["distance_m"] for r in results), 1),
            "seconds": round(sum(r["elapsed_s"] for r in results), 1)}


def autonomy_table(autonomy: dict) -> str:
    rows = ["| rule | mode | network | autonomy % (mean ± 95 % CI) | paper | runs x s | take-overs | by clause "
            "(take-overs, seconds) | collisions | while correcting | distance [m] |",
            "|---|---|---|---:|---:|---|---:|---|---:|---:|---:|"]
    for rule, modes in autonomy.items():
        for mode in EVALUATED:
            for net in ("MultiNet", "MTL"):
                a = autonomy_row(modes[mode][net])
                ci = f" ± {a['autonomy_ci95']:.2f}" if a["autonomy_ci95"] is not None else ""
                per_run = a["seconds"] / max(a["runs"], 1)
                rows.append(f"| {rule} | {mode} | {net} | **{a['autonomy_mean']:.2f}**{ci} | "
                            f"{PAPER['autonomy'][mode][net]} | {a['runs']} x {per_run:.0f} | "
                            f"{a['take_overs']} | {clause_text(a['clauses'])} | {a['collisions']} | "
                            f"{a['collisions_while_correcting']} | {a['distance_m']:.0f} |")
    return "\n".join(rows)


def _cell(a: dict) -> str:
    return f"{a['autonomy_mean']:.2f}" + (f" ± {a['autonomy_ci95']:.2f}" if a["autonomy_ci95"] is not None else "")


def drawn(results: list[dict]) -> str:
    """The conditions some runs drew, with how many runs drew each."""
    counts: dict[str, int] = {}
    for r in results:
        name = r.get("condition", SEEDED)   # a run recorded before conditions existed drew the seeded look
        counts[name] = counts.get(name, 0) + 1
    return ", ".join(f"{c} {n}" for c, n in sorted(counts.items()))


def conditions_summary(training: dict, held_out: dict) -> dict:
    """MultiNet and MTL per evaluated mode under the training conditions (`training`: {mode: {net: runs}}, the final
    runs of the study's rule) and the held-out ones (`held_out`: {condition: {mode: {net: runs}}}): every new
    condition's runs together and each on its own, the change from the training conditions, and whether MultiNet is
    ahead of the MTL net of the mode under the new conditions."""
    out: dict = {"conditions": list(held_out), "modes": {}}
    for mode in EVALUATED:
        row = {}
        for net in ("MultiNet", "MTL"):
            runs = [r for c in held_out.values() for r in c[mode][net]]
            a, b = autonomy_row(training[mode][net]), autonomy_row(runs)
            row[net] = {"training": a, "new": b, "change": round(b["autonomy_mean"] - a["autonomy_mean"], 2),
                        "drawn": drawn(training[mode][net]),
                        "by_condition": {c: autonomy_row(held_out[c][mode][net]) for c in held_out}}
        row["multinet_ahead"] = row["MultiNet"]["new"]["autonomy_mean"] > row["MTL"]["new"]["autonomy_mean"]
        out["modes"][mode] = row
    return out


def conditions_table(summary: dict, training: str) -> str:
    """The summary as a table: a row per mode and network, the training conditions beside the new ones."""
    held = summary["conditions"]
    rows = [f"| mode | network | training conditions ({training}) | runs drew | new conditions ({', '.join(held)}) "
            "| change | " + " | ".join(held) + " |", "|---|---|---:|---|---:|---:|" + "---:|" * len(held)]
    for mode, row in summary["modes"].items():
        for net in ("MultiNet", "MTL"):
            r = row[net]
            rows.append(f"| {mode} | {net} | {_cell(r['training'])} | {r['drawn']} | **{_cell(r['new'])}** | "
                        f"{r['change']:+.2f} | " + " | ".join(_cell(r["by_condition"][c]) for c in held) + " |")
    ahead = [f"{m} {'yes' if row['multinet_ahead'] else 'no'} ({row['MultiNet']['new']['autonomy_mean']:.2f} "
             f"against {row['MTL']['new']['autonomy_mean']:.2f})" for m, row in summary["modes"].items()]
    return "\n".join(rows) + "\n\nMultiNet ahead of the MTL net of the mode under the new conditions: " + \
        "; ".join(ahead) + "."


def rounds_table(study) -> tuple[str, dict]:
    rows = ["| network | round | mode | loop | autonomy % while recording | corrected steps | moments added |",
            "|---|---:|---|---|---:|---:|---:|"]
    added: dict = {}
    for name in ("multinet", "mtl-direct", "mtl-furtive"):
        for k in range(1, study.cfg.rounds + 1):
            for mode in study.net_modes(name):
                where = study.out / "rounds" / f"round{k}" / f"{name}-{mode}"
                r = json.loads((where / "autonomy.json").read_text())["rounds"][0]
                steps, moments = corrected_moments(where / "corrections-0")
                added[name] = added.get(name, 0) + moments
                rows.append(f"| {name} | {k} | {mode} | {r['path']} | {r['autonomy_percent']:.1f} | {steps} | "
                            f"{moments} |")
    return "\n".join(rows), added


def sizes(study) -> dict:
    from perception.checkpoint import load_checkpoint  # lazy: torch
    out = {}
    for name in study.nets():
        ckpt = load_checkpoint(study.models / f"{name}.pt")
        params = sum(v.numel() for k, v in ckpt["state_dict"].items()
                     if k.startswith("net.") and not k.endswith(("running_mean", "running_var", "num_batches_tracked")))
        out[name] = {"parameters": params, "mb": params * 4 / 1e6, "best": ckpt["train"]["best"],
                     "moments": ckpt["train"]["moments"], "minutes": round(ckpt["train"]["seconds"] / 60, 1)}
    return out


def times_table(timings: dict) -> str:
    rows = ["| step | wall [min] | CPU [min] |", "|---|---:|---:|"]
    rows += [f"| {k} | {v['wall_s'] / 60:.1f} | {v['cpu_s'] / 60:.1f} |" for k, v in timings.items()]
    return "\n".join(rows)


def write_report(study, baseline: dict, autonomy: dict, final: dict, seconds: float,
                 held_out: dict | None = None) -> Path:
    """STUDY.md, study.json and the figures of a finished study; the report is printed too. `held_out`:
    {condition: {mode: {net: runs}}} of the final runs under the new conditions (none: the study held none out)."""
    multi = summary(study.models / "multinet.pt")
    mtl = {m: summary(study.models / f"mtl-{m}.pt") for m in MODES}
    figures(study.out, multi, mtl)
    verdict = verdicts(multi, mtl)
    nets = sizes(study)
    rounds, added = rounds_table(study)
    data = data_summary(study, nets["multinet"]["moments"], added)
    wall = sum(v["wall_s"] for v in study.timings.values())
    cpu = sum(v["cpu_s"] for v in study.timings.values())
    c = study.cfg
    new = conditions_summary(autonomy[c.rule], held_out) if held_out else None
    text = report_text(study, data, multi, mtl, verdict, nets, rounds, autonomy, baseline, seconds,
                       new_conditions_text(study, new) if new else "")
    write_text(study.out / "STUDY.md", text)
    write_json(study.out / "study.json", {
        "config": vars(c) | {"loops": list(c.loop_names)}, "data": data, "validation": {"multinet": multi, "mtl": mtl},
        "verdicts": verdict, "final_networks": final, "sizes": nets,
        "minutes": round(wall / 60, 1), "cpu_minutes": round(cpu / 60, 1),
        "timings": study.timings,
        "autonomy": {rule: {mode: {net: autonomy_row(r) for net, r in nets_.items()} for mode, nets_ in m.items()}
                     for rule, m in autonomy.items()},
        "baseline": {rule: {mode: {net: autonomy_row(r) for net, r in nets_.items()} for mode, nets_ in m.items()}
                     for rule, m in baseline.items()},
        "new_conditions": new})
    print(text)
    return study.out / "STUDY.md"


def new_conditions_text(study, summary: dict) -> str:
    c = study.cfg
    return f"""
## Under new conditions (rule `{c.rule}`)

Percentage autonomy (mean ± 95 % CI over the runs) of the final networks on {', '.join(c.loop_names)} under the
conditions held out of the data and the rounds, each run once in each (`{study.out.name}/new-conditions/`), beside
the same runs under the training conditions, whose mix each run's seed draws from (as the data's episodes and the
rounds' drives do); the change is the new conditions' mean less the training conditions'. The issue's target:
MultiNet ahead of MTL in both modes under new conditions.

{conditions_table(summary, c.condition)}
"""


def data_summary(study, moments: dict, added: dict) -> dict:
    """What the study's data holds: steps, episodes, data moments, sizes on disk, loops, the corrections added."""
    manifest = json.loads((study.data / "manifest.json").read_text())
    return {"steps": manifest["frames"], "episodes": len(manifest["shards"]), "moments": moments,
            "shards_mb": round(sum(s["size"] for s in manifest["shards"]) / 1e6, 1),
            "cache_mb": round(folder_mb(study.data / ".frames"), 1),   # the frame cache (perception/frame_cache.py)
            "paths": sorted({s["params"]["path"] for s in manifest["shards"]}),
            "corrections_added": added,
            "correctional_share": {n: round(a / (a + moments["train"]), 4) for n, a in added.items()}}


def under(condition: str) -> str:
    return "" if condition == SEEDED else f", in the conditions {condition}"


def report_text(study, data: dict, multi: list[dict], mtl: dict, verdict: dict, nets: dict, rounds: str,
                autonomy: dict, baseline: dict, seconds: float, held_out: str = "") -> str:
    """STUDY.md: the data, the validation curves, the correction rounds, autonomy (`held_out`: its section under the
    new conditions), the sizes and the times."""
    c = study.cfg
    moments, added = data["moments"], data["corrections_added"]
    wall = sum(v["wall_s"] for v in study.timings.values())
    cpu = sum(v["cpu_s"] for v in study.timings.values())
    three = sum(nets[f"mtl-{m}"]["parameters"] for m in MODES)
    text = f"""# The MultiNet study, in simulation

`drivestudio study --out {study.out}` with {json.dumps({k: v for k, v in vars(c).items() if k != 'out'})}.
Took **{wall / 60:.0f} minutes** of wall time over every run of the command ({seconds / 60:.0f} in the last);
the steps' times are below. The paper: {PAPER['moments']:,} real moments,
{PAPER['epochs']} epochs, {PAPER['trials']} trials, {PAPER['correctional_share']:.2%} correctional data.

## Data

{data['steps']:,} steps in {data['episodes']} episodes (the three modes equally) over {len(data['paths'])} loops
({', '.join(data['paths'])}): **{moments['train'] + moments['validation']:,} data moments** ({moments['train']:,}
training, {moments['validation']:,} held out, whole episodes, the modes equal); {data['shards_mb']:,.0f} MB of shards,
{data['cache_mb']:,.0f} MB of moments cached at 94 x 168. The correction rounds added {added} moments
(correctional share {data['correctional_share']}).

## Validation loss per epoch (equation 2; mean over trials ± 95 % confidence half-width)

{validation_table(multi, mtl)}

From mid-training on (the second half of the epochs), MultiNet's mean validation loss is at or below the mean of the
three MTL nets' in {verdict['figure7'][0]} of {verdict['figure7'][1]} epochs, and on furtive moments at or below the
furtive MTL net's in {verdict['figure8'][0]} of {verdict['figure8'][1]}.

![Figure 7](figure7-all-modes.png) ![Figure 8](figure8-furtive.png)

For comparison, {PAPER_FIGURE7}; {PAPER_FIGURE8}.

## Correction rounds ({c.rounds}; rule `{c.rule}`)

{rounds}

## Percentage autonomy (the paper's section 4.4) on {', '.join(c.loop_names)}{under(c.condition)}

{autonomy_table(autonomy)}
""" + (f"""
Before the correction rounds (rule `{c.rule}`, {c.baseline_runs} run(s) per loop):

{autonomy_table(baseline)}
""" if baseline else "") + held_out + f"""
## Size

One MultiNet: {nets['multinet']['parameters']:,} parameters ({nets['multinet']['mb']:.2f} MB of float32); three MTL
nets together: {three:,} ({three / nets['multinet']['parameters']:.2f}x).

Times of the steps (wall and CPU seconds, over every run of the command: {wall / 60:.0f} minutes of wall time and
{cpu / 60:.0f} minutes of CPU time; the machine's 2 cores would do that CPU work in about {cpu / 120:.0f} minutes if
nothing else ran on them):

{times_table(study.timings)}
"""
    return text
