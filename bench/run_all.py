"""The benchmark suite: every benchmark of bench/ at sizes that finish in about 30 minutes on a 2-core machine (the
demo from a fresh clone among them), their figures in one table with the machine, the date and the versions.

    python -m bench                         # everything; writes docs/benchmarks.md (between its markers) and
                                            # bench/results.json
    python -m bench --quick --no-write      # a few seconds per bench, printed only (a smoke test)
    python -m bench --only render,bridge    # some benches; their rows replace those of the last full run

Each bench runs as its own process (`python bench/bench_NAME.py ... --json FILE`), prints what it prints on its
own, and its JSON figures become rows of the table. A bench that fails is recorded as failed (with its last line
of error) and the others still run; the exit status is then 1. Figures measured on a machine shared with other
work are lower than on a quiet one: the header gives the load average at the start.
"""
from __future__ import annotations

import argparse
import importlib.metadata
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

BENCH = Path(__file__).resolve().parent
REPO = BENCH.parent
DOC = REPO / "docs" / "benchmarks.md"
RESULTS = BENCH / "results.json"
BEGIN, END = "<!-- BEGIN GENERATED bench-suite -->", "<!-- END GENERATED bench-suite -->"
SECTION = """## The suite
`python -m bench` runs every benchmark of `bench/` at sizes that finish in about 30 minutes on this machine (the
demo from a fresh clone among them) and writes the table below (and `bench/results.json`) with the machine, the date
and the versions; `--only NAME,...` reruns some of them (their rows replace those of the last run), `--quick
--no-write` is a smoke test (seconds per bench, MultiNet's and the demo's about a minute). highway-env is installed on
first use into its own environment (`.venv-highway-env/`), never into the project's. The load average is recorded
because this machine is shared: while other work runs, the figures that depend on threads waiting for each other (the
bridge's round trip, batch-1 inference with 2 torch threads) fall far more than the others; compare them with the
quiet figures above.

"""


def _f(x: float, digits: int = 0) -> str:
    return f"{x:,.{digits}f}"


# --- the figures of each bench as table rows: (figure, measured, target) ----------------------------------------
def rows_render(j: dict) -> list[tuple]:
    out = []
    for r in j["runs"]:
        insets = {"none": "", "mirror": ", with the mirror", "sides": ", with the mirror and the side views"}
        out.append((f"render + ground truth, {j['track']}, 3 lanes, 12 cars ahead, 280x210{insets[r['insets']]}, "
                    f"1 process, renderer {r['renderer']}",
                    f"**{_f(r['frames_per_s'])} frames/s** ({_f(r['frames_per_cpu_s'])} per CPU second; "
                    f"render {r['render_ms']:.2f} ms, truth {r['truth_ms']:.2f})",
                    ">= 1,000 frames/s (issue 48)" if r["renderer"] == "numba" else ""))
    out += [(f"renderer {name}", f"not run: {why}", "") for name, why in j.get("skipped", {}).items()]
    return out


def rows_conditions(j: dict) -> list[tuple]:
    out = [(f"render + ground truth in condition {x['condition']}, renderer {r}, oval, 280x210",
            f"**{_f(x['frames_per_s'])} frames/s** ({x.get('cost_vs_clear', float('nan')):.2f}x clear's cost)",
            "within 1.2x clear's (issue 49)" if r == "numba" else "")
           for r, rows in j["renderers"].items() for x in rows]
    return out + [(f"renderer {name}", f"not run: {why}", "") for name, why in j.get("skipped", {}).items()]


def rows_traffic(j: dict) -> list[tuple]:
    return [(f"world + SUMO + truth at 10 Hz, {r['cars']} cars, no rendering",
             f"**{_f(r['steps_per_s'])} steps/s** ({_f(r['realtime_factor'])}x real time; "
             f"{r['sim_ms_per_step']:.2f} ms world, {r['driver_ms_per_step']:.2f} ms driver)",
             ">= 1,000 steps/s" if r["cars"] == 12 else "") for r in j["runs"]]


def rows_gym_worlds(j: dict) -> list[tuple]:
    one = j["one_world"]
    before = (f"; {j['base']}: {_f(one['base'])}, ratio {one['ratio']:.2f} (per CPU second {one['ratio_cpu']:.2f})"
              if j.get("base") else "")
    out = [("Gymnasium steps/s, drivestudio/Highway-v0 (oval, 3 lanes, 12 cars, a 280x210 frame, Chen on the truth), "
            "one world", f"**{_f(one['this'])} steps/s** (median of {j['rounds']}; {_f(one['this_cpu'])} per CPU "
            f"second){before}",
            "not below the single-world speed before many worlds (issue 24)")]
    for r, v in j.get("renderers", {}).items():
        out.append((f"same, renderer {r}", f"**{_f(v['steps_per_s'])} steps/s** ({_f(v['steps_per_cpu_s'])} per CPU "
                    f"second; {v['steps_per_s'] / one['this']:.2f}x the default's)",
                    ">= 700 steps/s (issue 48)" if r == "numba" else ""))
    out.append(("same, affordance observation (no frame)", f"{_f(j['affordances'])} steps/s", ""))
    for m in j["many"]:
        out.append((f"same, {m['worlds']} worlds in one process (1 libsumo, {m['worlds'] - 1} TraCI), all together",
                    f"{_f(m['steps_per_s'])} steps/s", ""))
    return out


def _rows_bridge(j: dict, target: str) -> list[tuple]:
    lock, free = j["lockstep"], j.get("free_running")
    images = " + ".join("x".join(str(v) for v in (s[1], s[0], s[2])) for s in lock["images"])
    out = [(f"bridge round trip, {lock['world']} ({images} + truth one way, action back), lock-step",
            f"**median {lock['median_us']:.1f} µs**, p90 {lock['p90_us']:.1f}, p99 {lock['p99_us']:.1f}, max "
            f"{lock['max_us']:.0f}; {_f(lock['round_trips_per_s'])} round trips/s", target)]
    if free:
        out.append((f"bridge free-running, {lock['world']}",
                    f"{_f(free['published_per_s'])} frames/s published, {_f(free['taken_per_s'])} taken", ""))
    return out


def rows_bridge(j: dict) -> list[tuple]:
    return _rows_bridge(j, "median < 50 µs")


def rows_bridge_sidewalk(j: dict) -> list[tuple]:
    return _rows_bridge(j, "")


def rows_closed_loop(j: dict) -> list[tuple]:
    out = []
    for r in j["runs"]:
        st = r["stage_ms_per_step"]
        sim = st["physics"] + st["traffic"] + st["truth"]
        out.append((f"closed loop, {r['model']}, 2 processes over shared memory, lock-step, oval 3 lanes 12 cars",
                    f"**{_f(r['loop_hz'])} Hz** (ms a step: render {st['render']:.2f}, transfer {st['transfer']:.2f}, "
                    f"perception {st['perception']:.2f}, control {st['control']:.2f}, sim {sim:.2f})", ">= 60 Hz"))
    return out


def rows_dataset(j: dict) -> list[tuple]:
    return [("dataset generation, 280x210 PNG, default mix, 2 workers (end to end)",
             f"**{_f(j['generation_2_workers_frames_per_s'])} frames/s**", ">= 200 frames/s"),
            ("same, 1 worker", f"{_f(j['generation_1_worker_frames_per_s'])} frames/s", ""),
            ("training loader (FrameStream + DataLoader, decode to tensors), 2 loader workers",
             f"**{_f(j['stream_2_workers_frames_per_s'])} frames/s** ({_f(j['stream_0_workers_frames_per_s'])} in "
             f"the main process, {_f(j['stream_1_workers_frames_per_s'])} with 1 worker)", ">= 2,000 frames/s"),
            ("random access (FrameDataset), 1 process", f"{_f(j['random_access_frames_per_s'])} frames/s", "")]


def rows_perception(j: dict) -> list[tuple]:
    return [(f"{r['model']} on {j['on']}", f"train {r['train_samples_per_s']:.1f} samples/s (batch {r['batch']}), "
             f"inference {r['infer_frames_per_s']:.1f} frames/s (batch 32), latency {r['latency_ms']:.1f} ms (1)",
             "reported") for r in j["models"]]


def rows_training(j: dict) -> list[tuple]:
    return [(f"training {r['family']}, {r['configuration']}, real frames ({j['frames']}), data loading included",
             f"**{_f(r['samples_per_s'])} samples/s** ({r['vs_before']:.2f}x before)",
             ">= 1.5x before (AlexNet)" if r["family"] == "alexnet" else "reported") for r in j["rows"]]


def rows_stereo(j: dict) -> list[tuple]:
    p = j["render_pair"]
    out = [(f"sidewalk stereo pair drawn (2 x 336x188), 1 process, compiled kernels against OpenCV's fills, the same "
            f"{p['pairs_a_round']} poses, median of {p['rounds']} alternating rounds, {p['cpu']}",
            f"**{p['numba_wall_ms']:.2f} ms a pair** ({p['numba_cpu_ms']:.2f} CPU), OpenCV's {p['opencv_wall_ms']:.2f} "
            f"({p['opencv_cpu_ms']:.2f} CPU): **{p['ratio_wall']:.2f}x** ({p['ratio_cpu']:.2f}x CPU)",
            ">= 3x (issue 48)")]
    if "breakdown_ms_per_step" not in j:   # --render-only
        return out
    b = j["breakdown_ms_per_step"]
    out += [("sidewalk generation, 336x188 x 2 cameras PNG, 2 workers (end to end)",
            f"**{_f(j['generation_2_workers_steps_per_s'])} steps/s** ({_f(j['generation_1_worker_steps_per_s'])} "
            f"with 1 worker; one process: " + ", ".join(f"{k} {v:.2f}" for k, v in b.items()) + " ms a step)",
            ">= 150 steps/s")]
    for mode, r in j["closed_loop"].items():
        out.append((f"sidewalk closed loop, expert {mode}, 2 processes, lock-step", f"**{_f(r['loop_hz'])} Hz**",
                    ">= 60 Hz"))
    for mode, r in j["safety"].items():
        out.append((f"sidewalk expert {mode}, {j['minutes']:g} simulated min on procedural:11",
                    f"{r['collisions']} collisions, {r['off_path_time_s']} s off the path, {r['obstacles_met']} "
                    f"obstacles met, {r['mean_speed_mps']:.2f} m/s", "0 collisions, 0 s off the path"))
    return out


def rows_benchmark(j: dict) -> list[tuple]:
    suite = json.loads((REPO / "assets" / "suites" / "default.json").read_text())
    full = sum(r["seconds"] for r in suite["routes"])
    oracle = next((m for m in j["models"] if m["model"] == "oracle"), j["models"][0])
    return [(f"`drivestudio benchmark`, routes {', '.join(j['routes'])} of the '{j['suite']}' suite, "
             f"{j['workers']} workers ({j['transport']})",
             f"{j['simulated_s'] / 60:.1f} simulated min in {j['wall_s']:.0f} s (**{j['realtime_factor']:.1f}x real "
             f"time**; the whole suite, {full / 60:.0f} simulated min, would take about "
             f"{full / j['realtime_factor'] / 60:.1f} min); oracle DS {oracle['driving_score']:.0%}",
             "default suite <= 10 min")]


def rows_multinet(j: dict) -> list[tuple]:
    inf, tr, loop = j["inference"], j["training"], j["closed_loop"]
    onnx = f"{inf['onnx_ms_batch1']:.2f} ms" if inf.get("onnx_ms_batch1") is not None else "not installed"
    return [(f"Z2Color MultiNet inference, one data moment (4 x 336x188), batch 1, {inf['threads']} threads",
             f"**PyTorch {inf['torch_ms_batch1']:.2f} ms**, ONNX Runtime {onnx}; batch 32: "
             f"{inf['torch_ms_per_moment_batch32']:.2f} ms a moment", "<= 5 ms"),
            (f"MultiNet training on cached moments (Adadelta, batch {tr['batch']}, balanced modes, clipping; "
             "channels-last, bfloat16 autocast, prefetch)",
             f"**{_f(tr['moments_per_s'])} moments/s** ({_f(tr.get('before_moments_per_s', 0))} as before: float32, "
             "default layout; alternate rounds)", ">= 250 moments/s"),
            *([("MultiNet training, two one-thread trainings side by side (the study's setting)",
                f"**{_f(sbs['moments_per_s_each'])} moments/s each**; a batch assembled in {sbs['assembly_ms']:.0f} ms "
                f"through the pixel table ({sbs['assembly_before_ms']:.0f} ms before it)", "reported")]
              if (sbs := tr.get("side_by_side")) else []),
            ("MultiNet closed loop over shared memory, sidewalk, lock-step", f"**{_f(loop['loop_rate_hz'])} Hz**",
             ">= 30 Hz")]


def rows_highway_env(j: dict) -> list[tuple]:
    if not j.get("measured"):
        return [("drivestudio Highway-v0 vs highway-env highway-v0", "not measured: " + j.get("reason", "?"), "")]
    t = j["theirs"]
    pf = t["config"]["policy_frequency"]
    n = t["frames_per_step"]
    return [(f"Gymnasium steps/s, a 280x210 frame every step: drivestudio/Highway-v0 (3-D, oval, 3 lanes, 12 cars, "
             f"Chen on the truth) vs highway-env {t['versions']['highway-env']} highway-v0 (3 lanes, 12 vehicles, "
             f"IDLE, policy_frequency {pf}" + (" as shipped" if pf == 1 else "") + "), alternating, median of "
             f"{len(j['rounds'])} rounds of {j['steps_per_round']}",
             f"ours {_f(j['ours_steps_per_s'])}, highway-env {_f(j['theirs_steps_per_s'])}: **ratio "
             f"{j['ratio']:.2f}** (rounds {j['ratio_range'][0]:.2f}-{j['ratio_range'][1]:.2f})", "reported"),
            (f"same, simulated time: a step is {j['ours']['seconds_per_step']:g} s for ours, "
             f"{t['seconds_per_step']:.3g} s ({n} simulation frame{'s' if n != 1 else ''}"
             + (", all drawn" if n > 1 else "") + ") for highway-v0",
             f"x real time: ours {j['ours_realtime_factor']:.1f}, highway-env {j['theirs_realtime_factor']:.1f}", "")]


def rows_commands(j: dict) -> list[tuple]:
    out = []
    for r in j["commands"]:
        argv = r["argv"][:r["argv"].index("--out")]
        figure = f"**{r['minutes']:.1f} minutes** ({r['cpu_minutes']:.0f} CPU minutes)" if r["status"] == 0 else \
            f"failed (exit {r['status']})"
        random = r.get("random_suite", {}).get("drivers")
        if random:
            figure += f"; its driver {random[0]['percent_of_oracle-extended']:.1f} % of the extended oracle on the " \
                      f"random suite, {random[0]['collisions']} collisions in {random[0]['km']:.1f} km"
        target = f"<= {r['target_minutes']:g} minutes (issue 48)" if r["target_minutes"] else ""
        out.append((f"`drivestudio {' '.join(argv)}` from a fresh clone, {j['machine']['cores']} cores", figure,
                    target))
    return out


def _slowdown(x: float) -> str:
    return f"{x:.1%} slower" if x >= 0 else f"no slowdown: {-x:.1%} faster"


def rows_studio(j: dict) -> list[tuple]:
    targets = {"highway camera, as fast as it can": ">= 30 frames/s",
               "sidewalk stereo pair, real time (30 Hz)": ">= 20 frames/s"}
    out = [(f"studio: frames drawn in the page (headless Chromium), {name}",
            f"**{r['frames_per_s']:.0f} frames/s** (loop {r['loop_hz']:.0f} Hz, {r['kb_per_frame']:.0f} kB a frame)",
            targets.get(name, "")) for name, r in j["frames"].items()]
    out += [(f"studio: key press to a changed command in the page, {w}, real time",
             f"**median {r['median_ms']:.0f} ms**, p95 {r['p95_ms']:.0f}, max {r['max_ms']:.0f} ({r['measured']} "
             "presses)", "<= 100 ms") for w, r in j["latency"].items()]
    for how, r in j["view"].items():
        by = "a page in Chromium on the same cores" if how == "browser" else \
            "a protocol client (takes and acknowledges every frame, draws nothing)"
        out.append((f"`drive --view` watched by {by} vs not, highway oracle, lock-step, alternating windows",
                    f"**{_slowdown(r['median_slowdown'])}** (median of {r['windows']} windows of "
                    f"{r['window_s']:g} s, quartiles {r['quartiles'][0]:+.1%} to {r['quartiles'][-1]:+.1%} slower; "
                    f"{r['watched_hz']:.0f} against "
                    f"{r['unwatched_hz']:.0f} Hz); CPU a step, watched and not: loop thread "
                    f"{r['loop_thread_ms'][0]:.2f}, {r['loop_thread_ms'][1]:.2f} ms, server threads "
                    f"{r['server_threads_ms'][0]:.2f}, {r['server_threads_ms'][1]:.2f} ms"
                    + (f"; the browser {r['browser_cpu_share']:.0%} of a core" if how == "browser" else ""),
                    "<= 10 %"))
    return out


@dataclass
class Bench:
    name: str
    script: str
    full: list[str]
    quick: list[str]
    rows: Callable[[dict], list[tuple]]
    group: str = ""
    temp_out: bool = False      # give it an --out folder in a temporary directory
    extra: list[str] = field(default_factory=list)


BENCHES = [
    Bench("render", "bench_render.py", ["--frames", "1000", "--rounds", "3"],
          ["--frames", "30", "--rounds", "1", "--renderers", "tiny,numba", "--insets", "none"], rows_render),
    Bench("conditions", "bench_conditions.py", ["--frames", "600", "--rounds", "3"],
          ["--frames", "20", "--rounds", "1", "--renderers", "numba", "--conditions", "clear,fog"], rows_conditions),
    Bench("gym-worlds", "bench_gym_worlds.py", ["--rounds", "5", "--steps", "300", "--renderers", "numba,gl"],
          ["--rounds", "1", "--steps", "20"], rows_gym_worlds),
    Bench("traffic", "bench_traffic.py", ["--cars", "12", "50", "100", "--seconds", "300"],
          ["--cars", "12", "--seconds", "20"], rows_traffic),
    Bench("bridge", "bench_bridge.py", ["--trips", "5000"],
          ["--trips", "300", "--warmup", "50", "--free-seconds", "0.2"], rows_bridge, group="bridge"),
    Bench("bridge-sidewalk", "bench_bridge.py", ["--world", "sidewalk", "--trips", "5000"],
          ["--world", "sidewalk", "--trips", "300", "--warmup", "50", "--free-seconds", "0.2"], rows_bridge_sidewalk,
          group="bridge"),
    Bench("closed-loop", "bench_closed_loop.py", ["--seconds", "60"], ["--seconds", "3"], rows_closed_loop),
    Bench("dataset", "bench_dataset.py", ["--frames", "4000"], ["--frames", "200"], rows_dataset, temp_out=True),
    Bench("perception", "bench_perception.py", ["--steps", "3"], ["--steps", "1", "--models", "alexnet,gist"],
          rows_perception),
    Bench("training", "bench_training.py", ["--frames", "600", "--rounds", "2"],
          ["--frames", "60", "--rounds", "1", "--families", "mobilenet"], rows_training),
    Bench("stereo", "bench_stereo.py", ["--frames", "3000", "--seconds", "30", "--minutes", "3"],
          ["--frames", "200", "--seconds", "3", "--minutes", "0.2", "--rounds", "1"], rows_stereo, temp_out=True),
    Bench("benchmark", "bench_benchmark.py", ["--routes", "p21-1l,p9-1l", "--workers", "2"],
          ["--routes", "p21-1l", "--workers", "1"], rows_benchmark),
    Bench("multinet", "bench_multinet.py", ["--repeats", "100", "--seconds", "20"],
          ["--repeats", "5", "--seconds", "2"],
          rows_multinet),
    Bench("studio", "bench_studio.py",
          ["--seconds", "10", "--presses", "20", "--windows", "12", "--window", "5"],
          ["--seconds", "2", "--presses", "3", "--windows", "3", "--window", "2"], rows_studio),
    Bench("highway-env", "bench_highway_env.py", ["--steps", "200", "--rounds", "5"],
          ["--steps", "20", "--rounds", "2"],
          rows_highway_env, group="highway-env"),
    Bench("highway-env-15hz", "bench_highway_env.py", ["--steps", "200", "--rounds", "5", "--policy-frequency", "15"],
          ["--steps", "20", "--rounds", "2", "--policy-frequency", "15"], rows_highway_env, group="highway-env"),
    Bench("commands", "bench_commands.py", ["--commands", "demo"], ["--commands", "demo", "--quick"], rows_commands),
]


# --- the machine and the software ------------------------------------------------------------------------------
def machine() -> dict:
    cpu = platform.processor() or platform.machine()
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                cpu = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    memory = None
    try:
        kb = next(int(ln.split()[1]) for ln in Path("/proc/meminfo").read_text().splitlines()
                  if ln.startswith("MemTotal"))
        memory = round(kb / 2**20, 1)
    except (OSError, StopIteration, ValueError):
        pass
    gpu = None
    if shutil.which("nvidia-smi"):
        r = subprocess.run(["nvidia-smi", "--query-gpu=name", "--format=csv,noheader"], capture_output=True,
                           text=True)
        gpu = ", ".join(ln.strip() for ln in r.stdout.splitlines() if ln.strip()) or None
    return {"cpu": cpu, "arch": platform.machine(), "cores": os.cpu_count(), "memory_gib": memory, "gpu": gpu,
            "os": f"{platform.system()} {platform.release()}",
            "load_average": [round(x, 2) for x in os.getloadavg()]}


def highway_env_version() -> str | None:
    for info in (REPO / ".venv-highway-env").glob("lib/python*/site-packages/highway_env-*.dist-info"):
        return info.name[:-len(".dist-info")].split("-")[1]
    return None


def uncovered() -> list[str]:
    """Benchmark scripts of bench/ that the suite does not run."""
    known = {b.script for b in BENCHES}
    return sorted(p.name for p in BENCH.glob("bench_*.py") if p.name not in known)


def versions() -> dict:
    out: dict[str, str | None] = {"python": platform.python_version()}
    for name, pkg in (("torch", "torch"), ("pybullet", "pybullet"), ("libsumo", "libsumo"), ("numpy", "numpy"),
                      ("OpenCV", "opencv-python-headless"), ("pyarrow", "pyarrow"), ("gymnasium", "gymnasium")):
        try:
            out[name] = importlib.metadata.version(pkg)
        except importlib.metadata.PackageNotFoundError:
            out[name] = None
    out["highway-env"] = highway_env_version()
    return out


# --- running -----------------------------------------------------------------------------------------------------
def run_bench(b: Bench, quick: bool, tmp: Path, timeout: float, echo: bool) -> dict:
    out_json = tmp / f"{b.name}.json"
    args = list(b.quick if quick else b.full)
    if b.temp_out:
        args += ["--out", str(tmp / f"{b.name}-data")]
    cmd = [sys.executable, str(BENCH / b.script), *args, "--json", str(out_json)]
    shown = " ".join(["bench/" + b.script, *(a for a in args if not a.startswith(str(tmp)))]).replace(" --out", "")
    print(f"\n=== {b.name}: {shown}", flush=True)
    load = round(os.getloadavg()[0], 1)
    t0 = time.perf_counter()
    env = dict(os.environ, PYTHONUNBUFFERED="1")
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(REPO), env.get("PYTHONPATH")]))
    try:
        proc = subprocess.run(cmd, cwd=REPO, env=env, timeout=timeout, text=True,
                              stdout=None if echo else subprocess.PIPE, stderr=subprocess.PIPE)
        rc, err, out = proc.returncode, proc.stderr or "", proc.stdout or ""
    except subprocess.TimeoutExpired:
        rc, err, out = -1, f"timed out after {timeout:.0f} s", ""
    seconds = time.perf_counter() - t0
    if not echo and out:
        print(out, end="", flush=True)
    entry = {"name": b.name, "command": shown, "seconds": round(seconds, 1), "date": time.strftime("%Y-%m-%d %H:%M"),
             "quick": quick, "load_average": load}
    if rc != 0 or not out_json.exists():
        lines = [ln for ln in err.strip().splitlines() if ln.strip()]
        entry.update(status="failed", error=lines[-1] if lines else f"exit status {rc}")
        print(f"{b.name} FAILED ({entry['error']})", file=sys.stderr, flush=True)
        return entry
    figures = json.loads(out_json.read_text())
    entry.update(status="ok" if figures.get("measured", True) else "not measured", figures=figures)
    try:
        entry["rows"] = [list(r) for r in b.rows(figures)]
    except (KeyError, TypeError, ValueError, StopIteration) as e:
        entry.update(status="failed", error=f"its figures could not be read: {type(e).__name__}: {e}")
    return entry


def table(results: dict) -> str:
    m, v = results["machine"], results["versions"]
    gpu = m["gpu"] or "no GPU"
    head = (f"Measured {results['date']} by `python -m bench`{' --quick' if results.get('quick') else ''} "
            f"({results['seconds'] / 60:.1f} min): {m['cpu']} ({m['arch']}), {m['cores']} cores, "
            f"{m['memory_gib']} GiB, {gpu}, {m['os']}; load average {m['load_average'][0]:.1f} at the start"
            + (" (other work was running: the figures are lower than on a quiet machine)"
               if m["load_average"][0] > 0.5 * (m["cores"] or 1) else "") + ".  \n"
            + ", ".join(f"{k} {val or 'not installed'}" for k, val in v.items()) + ".\n")
    lines = [head, "| bench | figure | measured | target | run (s, load average at its start) |",
             "|---|---|---|---|---|"]
    older = []
    for name, e in results["benches"].items():
        run = f"`{e['command']}` ({e['seconds']:.0f} s" + (f", load {e['load_average']:.1f})" if "load_average" in e
                                                            else ")")
        if e.get("date", "") < results["date"][:16]:   # "YYYY-MM-DD HH:MM": before this run started
            older.append(f"{name} ({e.get('date')})")
        if e["status"] == "failed":
            lines.append(f"| {name} | | **failed**: {e['error'].replace('|', '/')} | | {run} |")
            continue
        for figure, measured, target in e["rows"]:
            lines.append(f"| {name} | {figure} | {measured} | {target} | {run} |")
            run = ""
    if older:
        lines.append(f"\nRows kept from earlier runs: {', '.join(older)}.")
    if results.get("uncovered"):
        lines.append(f"\nNot in the suite (add them to bench/run_all.py): {', '.join(results['uncovered'])}.")
    return "\n".join(lines) + "\n"


def write_doc(text: str, doc: Path = DOC) -> None:
    body = doc.read_text()
    block = f"{BEGIN}\n{text}{END}"
    if BEGIN in body and END in body:
        start, stop = body.index(BEGIN), body.index(END) + len(END)
        body = body[:start] + block + body[stop:]
    else:   # first time: a section after the table of targets, before the first "## " heading
        at = body.find("\n## ")
        at = len(body) if at < 0 else at + 1
        body = body[:at] + SECTION + block + "\n\n" + body[at:]
    tmp = doc.with_name(doc.name + ".tmp")
    tmp.write_text(body)
    tmp.replace(doc)


def select(only: str | None) -> list[Bench]:
    if not only:
        return list(BENCHES)
    names = [n.strip() for n in only.split(",") if n.strip()]
    known = {b.name for b in BENCHES} | {b.group for b in BENCHES if b.group}
    unknown = [n for n in names if n not in known]
    if unknown:
        raise SystemExit(f"python -m bench: no bench {', '.join(unknown)} (benches: "
                         f"{', '.join(b.name for b in BENCHES)})")
    return [b for b in BENCHES if b.name in names or (b.group and b.group in names)]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="a few seconds per bench (a smoke test; never written to "
                                                         "docs/benchmarks.md)")
    ap.add_argument("--only", metavar="NAME,...", help="run only these benches: " + ", ".join(
        b.name for b in BENCHES) + " (bridge: both worlds; highway-env: both settings)")
    ap.add_argument("--no-write", action="store_true", help="print the table only")
    ap.add_argument("--json", type=Path, help="also write the results to this file")
    ap.add_argument("--timeout", type=float, default=None, help="seconds a bench may take (default 1200; "
                                                                 "quick 300)")
    args = ap.parse_args(argv)
    benches = select(args.only)
    timeout = args.timeout or (300.0 if args.quick else 1200.0)
    t0 = time.perf_counter()
    results = {"date": time.strftime("%Y-%m-%d %H:%M %Z"), "quick": args.quick, "machine": machine(),
               "benches": {}}
    with tempfile.TemporaryDirectory(prefix="drivestudio-bench-") as tmp:
        for b in benches:
            results["benches"][b.name] = run_bench(b, args.quick, Path(tmp), timeout, echo=True)
    results["versions"] = versions()   # after the run: highway-env may have been installed by it
    results["uncovered"] = uncovered()
    results["seconds"] = round(time.perf_counter() - t0, 1)
    shown = results
    write = not args.no_write and not args.quick
    if write and args.only and RESULTS.exists():   # keep the other benches' rows of the last run
        old = json.loads(RESULTS.read_text())
        merged = {b.name: old["benches"][b.name] for b in BENCHES if b.name in old.get("benches", {})}
        merged.update(results["benches"])
        shown = {**results, "benches": {b.name: merged[b.name] for b in BENCHES if b.name in merged}}
    text = table(shown)
    print("\n" + text)
    if args.json:
        args.json.write_text(json.dumps(shown, indent=2, default=str) + "\n")
    if write:
        RESULTS.write_text(json.dumps(shown, indent=2, default=str) + "\n")
        write_doc(text)
        print(f"wrote {DOC.relative_to(REPO)} (between its bench-suite markers) and {RESULTS.relative_to(REPO)}")
    elif args.quick and not args.no_write:
        print("quick figures are a smoke test: nothing written (run without --quick to update docs/benchmarks.md)")
    failed = [n for n, e in results["benches"].items() if e["status"] == "failed"]
    if failed:
        print(f"failed: {', '.join(failed)}", file=sys.stderr)
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
