"""The whole commands timed as a newcomer runs them (issue 48's targets: `drivestudio demo` <= 6 minutes;
`drivestudio recipe --extended` <= 40, its driver >= 95 % of the extended oracle's score on the random suite;
`drivestudio study` <= 75 with its ordering and autonomy figures held).

Each command runs in a fresh clone of this checkout's HEAD (uncommitted changes are not timed), with this
interpreter and the clone's code first on the path, so that numba compiles its kernels and every dataset, cache
and network is made as on a fresh machine; only the installed environment is shared. A command's figure is its
wall time; its stages are timed from the moment each of its `== ` headers is printed; its CPU minutes are those of
all its processes. After the recipe its ensemble drives the random suite beside the extended oracle (timed apart,
not part of the recipe's minutes).

    python bench/bench_commands.py [--commands demo,recipe,study] [--quick] [--keep DIR] [--json F]

`--quick` runs each command's own --quick (a smoke test of this bench, not a figure). Each command's output goes to
the terminal and to DIR/NAME.log; DIR (a temporary folder unless --keep) holds the clones.
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
MEMORIES = "pass_memory=15,rear_memory=10"   # the extended recipe's ensemble, as the recipe drives it
COMMANDS = {"demo": (["demo", "--out", "out/demo"], 6.0),
            "recipe": (["recipe", "--extended", "--out", "out/recipe"], 40.0),
            "study": (["study", "--out", "out/study"], 75.0)}
EXACT = ("oracle", "oracle-extended")


def cpu_flags() -> dict:
    """The processor's model name and the flags that decide how the networks train (bfloat16 on AVX-512, AMX)."""
    try:
        info = Path("/proc/cpuinfo").read_text()
    except OSError:
        return {"cpu": "unknown", "bfloat16": []}
    lines = info.splitlines()
    name = next((ln.split(":", 1)[1].strip() for ln in lines if ln.startswith("model name")), "unknown")
    flags = next((ln.split(":", 1)[1].split() for ln in lines if ln.startswith("flags")), [])
    return {"cpu": name, "cores": os.cpu_count(), "bfloat16": [f for f in ("avx512_bf16", "amx_bf16") if f in flags]}


def clone(dest: Path) -> str:
    """A fresh clone of this checkout's HEAD at `dest`; returns its commit."""
    subprocess.run(["git", "clone", "-q", str(REPO), str(dest)], check=True)
    return subprocess.run(["git", "-C", str(dest), "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                          check=True).stdout.strip()


def cpu_seconds() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_timed(argv: list[str], cwd: Path, log: Path) -> dict:
    """`drivestudio ARGV` in the clone `cwd`, its output to the terminal and to `log`; wall and CPU minutes and the
    stages (each `== ` header's title, when it began and how long until the next)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(cwd), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep)}
    print(f"\n### drivestudio {' '.join(argv)}   (in {cwd})", flush=True)
    t0, c0, marks = time.perf_counter(), cpu_seconds(), []
    with log.open("w") as f, subprocess.Popen([sys.executable, "-m", "drivestudio", *argv], cwd=cwd, env=env,
                                              stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True) as p:
        assert p.stdout is not None
        for line in p.stdout:
            sys.stdout.write(line)
            f.write(line)
            if line.startswith("== "):
                marks.append((line[3:].split("  (")[0].strip(), time.perf_counter() - t0))
    wall = time.perf_counter() - t0
    ends = [at for _, at in marks[1:]] + [wall]
    stages = [{"title": title, "at_min": round(at / 60, 2), "minutes": round((end - at) / 60, 2)}
              for (title, at), end in zip(marks, ends)]
    return {"argv": argv, "status": p.returncode, "minutes": round(wall / 60, 2),
            "cpu_minutes": round((cpu_seconds() - c0) / 60, 1), "stages": stages}


def demo_quality(out: Path) -> dict:
    """How many of the 13 indicators the demo's MobileNet estimates with a lower MAE than GIST's."""
    models = json.loads((out / "highway" / "evaluate" / "evaluation.json").read_text())["models"]
    gist, mobilenet = (next(m["mae"] for m in models if m["spec"]["name"] == name) for name in ("gist", "mobilenet"))
    return {"mobilenet_below_gist": sum(mobilenet[k] < gist[k] for k in gist), "indicators": len(gist),
            "angle_mae": {"mobilenet": round(mobilenet["angle"], 4), "gist": round(gist["angle"], 4)}}


def board_quality(board: Path) -> dict:
    """Each learned driver's score as a percentage of each exact driver's on a leaderboard, its collisions and km."""
    table = json.loads(board.read_text())
    entries = table["models"]
    exact = {e["spec"]: e["overall"]["driving_score"] for e in entries if e["spec"] in EXACT}
    return {"suite": table["suite"].get("name"),
            "drivers": [{"spec": e["spec"], "collisions": e["overall"]["collisions"],
                         "km": e["overall"]["distance_km"],
                         **{f"percent_of_{k}": round(100 * e["overall"]["driving_score"] / v, 1) if v else None
                            for k, v in exact.items()}}
                        for e in entries if e["spec"] not in EXACT]}


def study_quality(out: Path) -> dict:
    """The study's percentage autonomy (mean over its runs) of each network, mode and correction rule."""
    study = json.loads((out / "study.json").read_text())
    return {"autonomy": {rule: {mode: {net: row["autonomy_mean"] for net, row in nets.items()}
                                for mode, nets in modes.items()} for rule, modes in study["autonomy"].items()},
            "stages": {k: round(v["wall_s"] / 60, 2) for k, v in study.get("timings", {}).items()}}


def first_route(suite: str) -> str:
    return json.loads((REPO / "assets" / "suites" / f"{suite}.json").read_text())["routes"][0]["name"]


def bench_command(name: str, root: Path, quick: bool) -> dict:
    argv, target = COMMANDS[name]
    here = root / name
    commit = clone(here)
    result = {"command": name, "commit": commit, "target_minutes": None if quick else target,
              **run_timed(argv + (["--quick"] if quick else []), here, root / f"{name}.log")}
    if result["status"] != 0:
        return result
    out = here / argv[argv.index("--out") + 1]
    if name == "demo":
        result["quality"] = demo_quality(out)
    elif name == "study":
        result["quality"] = study_quality(out)
    else:
        result["quality"] = {"suite": board_quality(out / "benchmark" / "leaderboard.json")} \
            if (out / "benchmark" / "leaderboard.json").is_file() else {}
        random = run_timed(["benchmark", "--suite", "random", "--model", "oracle-extended", "--model",
                            f"{out / 'ensemble.pt'}@{MEMORIES}", "--out", str(here / "out" / "random"),
                            *(["--routes", first_route("random")] if quick else [])], here, root / "recipe-random.log")
        result["random_suite"] = {"minutes": random["minutes"], "status": random["status"]}
        if random["status"] == 0:
            result["random_suite"] |= board_quality(here / "out" / "random" / "leaderboard.json")
    return result


def summary(r: dict) -> str:
    verdict = "" if r["target_minutes"] is None else \
        f" (target <= {r['target_minutes']:g}: {'met' if r['minutes'] <= r['target_minutes'] else 'MISSED'})"
    lines = [f"{r['command']}: {r['minutes']:.1f} minutes{verdict}, {r['cpu_minutes']:.0f} CPU minutes, "
             f"exit {r['status']}, commit {r['commit']}"]
    lines += [f"    {s['minutes']:6.2f} min  {s['title']}" for s in r["stages"]]
    if "quality" in r:
        lines.append(f"    quality: {json.dumps(r['quality'])}")
    if "random_suite" in r:
        lines.append(f"    afterwards, the random suite ({r['random_suite']['minutes']:.1f} min): "
                     f"{json.dumps(r['random_suite'].get('drivers'))}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--commands", default="demo,recipe,study", help="comma-separated: demo, recipe, study")
    ap.add_argument("--quick", action="store_true", help="each command's --quick (a smoke test, not a figure)")
    ap.add_argument("--keep", type=Path, help="keep the clones and logs in this folder (new or empty)")
    ap.add_argument("--json", type=Path, help="write the figures here")
    args = ap.parse_args(argv)
    names = [n for n in args.commands.split(",") if n]
    if not names or any(n not in COMMANDS for n in names):
        ap.error(f"--commands: one or more of {', '.join(COMMANDS)}")
    if args.keep and args.keep.exists() and any(args.keep.iterdir()):
        ap.error(f"--keep {args.keep}: not empty")
    if args.json and not os.access(args.json.resolve().parent, os.W_OK):   # refused before an hour of work
        ap.error(f"--json {args.json}: its folder is not writable")
    dirty = subprocess.run(["git", "-C", str(REPO), "status", "--porcelain", "--untracked-files=no"],
                           capture_output=True, text=True).stdout.strip()
    if dirty:
        print("note: uncommitted changes are not timed (each command runs from a clone of HEAD)", file=sys.stderr)
    root = args.keep or Path(tempfile.mkdtemp(prefix="drivestudio-commands-"))
    root.mkdir(parents=True, exist_ok=True)
    try:
        results = {"machine": cpu_flags(), "date": time.strftime("%Y-%m-%d %H:%M"), "quick": args.quick,
                   "commands": [bench_command(n, root, args.quick) for n in names]}
    finally:
        if not args.keep:
            shutil.rmtree(root, ignore_errors=True)
    m = results["machine"]
    print(f"\n{m['cpu']}, {m['cores']} cores, bfloat16: {', '.join(m['bfloat16']) or 'none'}; {results['date']}")
    for r in results["commands"]:
        print(summary(r))
    if args.json:
        args.json.write_text(json.dumps(results, indent=1) + "\n")
    return 0 if all(r["status"] == 0 for r in results["commands"]) else 1


if __name__ == "__main__":
    sys.exit(main())
