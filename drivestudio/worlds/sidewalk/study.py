"""The MultiNet study in one command (Chowdhuri, Pankaj and Zipser, MultiNet, 2017, sections 4.2-4.4, in simulation):

    python -m drivestudio.worlds.sidewalk.study --out out/study [--steps 4000] [--epochs 8] [--trials 3] [--seconds 60]

1. a balanced data-moment set of the sidewalk world (direct, follow, furtive);
2. MultiNet (Z2Color with modal insertion) on all of it, and three MTL nets (no modal input), each on one mode's
   data, `trials` times each with fresh seeds, validated every epoch on the last step (equation 2);
3. the paper's Figure 7 (MultiNet's validation loss against the mean of the three MTL nets') and Figure 8 (furtive
   mode: MultiNet against the furtive MTL net), means over trials with 95 % confidence intervals;
4. percentage autonomy in direct and in furtive mode, MultiNet against the MTL net of that mode, on a held-out
   loop with obstacles under the expert's correction;
5. STUDY.md with the tables beside the paper's numbers, the sizes of the networks, and the plots.

Every step goes through the same verbs a user runs (generate, train, autonomy, export); a step whose output exists
is skipped, so an interrupted study continues where it stopped.
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

MODES = ("direct", "follow", "furtive")
PAPER = {"autonomy": {"direct": {"MultiNet": 92.68, "MTL": 84.27}, "furtive": {"MultiNet": 88.23, "MTL": 87.55}},
         "parameters": "no more than 1.7 M (about 6.5 MB)", "moments": 1_930_000, "epochs": 24, "trials": 8}


def _cli(*argv) -> None:
    from drivestudio.cli import main
    print("$ drivestudio " + " ".join(map(str, argv)), flush=True)
    rc = main([str(a) for a in argv])
    if rc != 0:
        raise SystemExit(rc)


def _curves(path: Path) -> list[dict]:
    import csv
    with open(str(path) + ".curves.csv") as f:
        return [{k: (float(v) if v not in ("", None) else None) for k, v in row.items()} for row in csv.DictReader(f)]


def figure(out: Path, multi: list[dict], mtl: dict, key_multi: str, keys_mtl: dict, title: str, name: str) -> Path:
    """Validation loss per epoch with 95 % confidence bands: MultiNet against MTL (one net, or the mean of several)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 4), dpi=110)
    x = [r["epoch"] for r in multi]
    m = np.array([r[f"{key_multi}_mean"] for r in multi])
    c = np.array([r.get(f"{key_multi}_ci95") or 0.0 for r in multi])
    ax.plot(x, m, "o-", color="C0", label="MultiNet", markersize=3)
    ax.fill_between(x, m - c, m + c, color="C0", alpha=0.2)
    series = [np.array([r["val_loss_mean"] for r in mtl[k]]) for k in keys_mtl]
    cis = [np.array([r.get("val_loss_ci95") or 0.0 for r in mtl[k]]) for k in keys_mtl]
    mean = np.mean(series, axis=0)
    ci = np.sqrt(np.sum(np.square(cis), axis=0)) / len(series)   # the mean of independent nets' means
    label = "MTL" if len(series) == 1 else f"MTL (mean of {len(series)} nets)"
    ax.plot(x, mean, "s--", color="C3", label=label, markersize=3)
    ax.fill_between(x, mean - ci, mean + ci, color="C3", alpha=0.2)
    ax.set_xlabel("epoch")
    ax.set_ylabel("validation loss, last step (eq. 2)")
    ax.set_title(title, fontsize=9)
    ax.grid(alpha=0.3)
    ax.legend()
    from matplotlib.ticker import MaxNLocator
    ax.xaxis.set_major_locator(MaxNLocator(integer=True))
    fig.tight_layout()
    path = out / name
    fig.savefig(path)
    plt.close(fig)
    return path


def run(out: Path, steps: int, epochs: int, trials: int, seconds: float, batch: int, seed: int) -> Path:
    t0 = time.perf_counter()
    out.mkdir(parents=True, exist_ok=True)
    data, models = out / "data", out / "models"
    timings = {}

    def timed(name, fn, *a):
        t = time.perf_counter()
        fn(*a)
        timings[name] = round(time.perf_counter() - t, 1)

    if not (data / "manifest.json").exists() or not json.loads((data / "manifest.json").read_text())["complete"]:
        timed("generate", _cli, "generate", "--world", "sidewalk", "--out", data, "--frames", steps,
              "--episode-frames", 150, "--seed", seed, "--quiet")
    nets = {"multinet": []} | {f"mtl-{m}": ["--mtl", m] for m in MODES}
    for name, extra in nets.items():
        ckpt = models / f"{name}.pt"
        if not ckpt.exists() or Path(str(ckpt) + ".state").exists():
            timed(f"train {name}", _cli, "train", "--data", data, "--model", "z2color", "--out", ckpt, *extra,
                  "--epochs", epochs, "--trials", trials, "--batch-size", batch, "--seed", seed, "--device", "cpu")
    multi = _curves(models / "multinet.pt")
    mtl = {m: _curves(models / f"mtl-{m}.pt") for m in MODES}
    fig7 = figure(out, multi, mtl, "val_loss", MODES, "All modes: MultiNet vs the mean of the three MTL nets "
                  "(the paper's Figure 7)", "figure7-all-modes.png")
    fig8 = figure(out, multi, mtl, "val_loss_furtive", ("furtive",), "Furtive mode: MultiNet vs the furtive MTL net "
                  "(the paper's Figure 8)", "figure8-furtive.png")
    autonomy = {}
    for mode in ("direct", "furtive"):
        for name, ckpt in (("MultiNet", "multinet"), ("MTL", f"mtl-{mode}")):
            where = out / f"autonomy-{mode}-{ckpt}"
            if not (where / "autonomy.json").exists():
                timed(f"autonomy {mode} {ckpt}", _cli, "autonomy", "--model", models / f"{ckpt}.pt", "--mode", mode,
                      "--seconds", seconds, "--seed", seed, "--out", where)
            autonomy.setdefault(mode, {})[name] = json.loads((where / "autonomy.json").read_text())["rounds"][0]
    sizes = {}
    from perception.checkpoint import load_checkpoint
    for name in nets:
        ckpt = load_checkpoint(models / f"{name}.pt")
        # the network's learned parameters (not batch-norm statistics, nor the input scaling's buffers)
        params = sum(v.numel() for k, v in ckpt["state_dict"].items()
                     if k.startswith("net.") and not k.endswith(("running_mean", "running_var", "num_batches_tracked")))
        sizes[name] = {"parameters": params, "mb": params * 4 / 1e6, "best": ckpt["train"]["best"],
                       "moments": ckpt["train"]["moments"]}
    report = write_report(out, multi, mtl, autonomy, sizes, fig7, fig8, dict(steps=steps, epochs=epochs, trials=trials,
                          seconds=seconds, batch=batch, seed=seed), timings, time.perf_counter() - t0)
    return report


def mid_training_verdict(multi: list[dict], mtl: dict) -> tuple[int, int]:
    """(epochs from mid-training on where MultiNet's mean validation loss is at or below the MTL nets' mean, those
    epochs)."""
    n = len(multi)
    later = range(n // 2, n)
    mtl_mean = [np.mean([mtl[m][i]["val_loss_mean"] for m in MODES]) for i in range(n)]
    return int(sum(bool(multi[i]["val_loss_mean"] <= mtl_mean[i]) for i in later)), len(later)


def write_report(out, multi, mtl, autonomy, sizes, fig7, fig8, settings, timings, seconds) -> Path:
    rows = ["| epoch | MultiNet (all modes) | MTL mean of 3 | MTL direct | MTL follow | MTL furtive "
            "| MultiNet, furtive moments |", "|---:|---:|---:|---:|---:|---:|---:|"]

    def fmt(r, key):
        v, c = r.get(f"{key}_mean"), r.get(f"{key}_ci95")
        return "-" if v is None else f"{v:.4f}" + (f" ± {c:.4f}" if c else "")

    for i, r in enumerate(multi):
        mean = np.mean([mtl[m][i]["val_loss_mean"] for m in MODES])
        rows.append(f"| {int(r['epoch'])} | {fmt(r, 'val_loss')} | {mean:.4f} | " + " | ".join(
            fmt(mtl[m][i], "val_loss") for m in MODES) + f" | {fmt(r, 'val_loss_furtive')} |")
    won, of = mid_training_verdict(multi, mtl)
    auto = ["| mode | MultiNet autonomy % | MTL autonomy % | paper MultiNet | paper MTL | MultiNet take-overs | MTL "
            "take-overs | MultiNet distance [m] | MTL distance [m] |", "|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for mode in ("direct", "furtive"):
        a, b = autonomy[mode]["MultiNet"], autonomy[mode]["MTL"]
        p = PAPER["autonomy"][mode]
        auto.append(f"| {mode} | {a['autonomy_percent']:.2f} | {b['autonomy_percent']:.2f} | {p['MultiNet']} | "
                    f"{p['MTL']} | {a['corrections']} | {b['corrections']} | {a['distance_m']:.0f} | "
                    f"{b['distance_m']:.0f} |")
    size = ["| network | parameters | float32 MB | best (trial, epoch, val loss) | training / held-out moments |",
            "|---|---:|---:|---|---|"]
    for name, s in sizes.items():
        b = s["best"]
        size.append(f"| {name} | {s['parameters']:,} | {s['mb']:.2f} | {b['trial']}, {b['epoch']}, "
                    f"{b['val_loss']:.4f} | {s['moments']['train']} / {s['moments']['validation']} |")
    three = sum(sizes[f"mtl-{m}"]["parameters"] for m in MODES)
    text = f"""# The MultiNet study, in simulation

Settings: {settings['steps']} sidewalk steps (balanced modes), Z2Color trained {settings['trials']} trial(s) x
{settings['epochs']} epochs (Adadelta, batch {settings['batch']}, modes equally represented in batches and in the
held-out data), autonomy over {settings['seconds']:g} simulated seconds per run on the held-out loop
`procedural:907`. Took {seconds / 60:.0f} minutes. The paper: {PAPER['moments']:,} real moments, {PAPER['epochs']}
epochs, {PAPER['trials']} trials.

## Validation loss per epoch (equation 2; mean over trials ± 95 % confidence half-width)

{chr(10).join(rows)}

From mid-training on (the second half of the epochs), MultiNet's mean validation loss is at or below the mean of
the three MTL nets' in {won} of {of} epochs.

![Figure 7](figure7-all-modes.png) ![Figure 8](figure8-furtive.png)

## Percentage autonomy (the paper's section 4.4)

{chr(10).join(auto)}

## Size

{chr(10).join(size)}

One MultiNet: {sizes['multinet']['parameters']:,} parameters; three MTL nets together: {three:,}
({three / sizes['multinet']['parameters']:.2f}x).

Step timings [s]: {json.dumps(timings)}
"""
    from drivestudio.outputs import write_json, write_text
    write_text(out / "STUDY.md", text)
    write_json(out / "study.json", {"settings": settings, "validation": {"multinet": multi, "mtl": mtl},
                                    "autonomy": autonomy, "sizes": sizes, "mid_training": [won, of],
                                    "timings": timings, "minutes": round(seconds / 60, 1)})
    print(text)
    return out / "STUDY.md"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m drivestudio.worlds.sidewalk.study",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="out/study")
    ap.add_argument("--steps", type=int, default=4000, help="sidewalk steps to record (default 4000)")
    ap.add_argument("--epochs", type=int, default=8, help="epochs per trial (default 8)")
    ap.add_argument("--trials", type=int, default=3, help="trials per network (default 3)")
    ap.add_argument("--seconds", type=float, default=60.0, help="simulated seconds per autonomy run (default 60)")
    ap.add_argument("--batch-size", type=int, default=60, help="moments per batch (default 60)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    run(Path(args.out), args.steps, args.epochs, args.trials, args.seconds, args.batch_size, args.seed)
    return 0


if __name__ == "__main__":
    sys.exit(main())
