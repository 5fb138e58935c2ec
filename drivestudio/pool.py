"""One pool for every verb that runs work side by side: `generate`'s episodes, `benchmark`'s routes, the recipes'
trainings and aggregation rounds, the study's trainings and drives. Two backends: local child processes, and Ray
tasks on a cluster (docs/scaling.md).

A job is a call or a command:
- a call, `Job(name, call="module:function", args={...})`: function(args, progress) -> result, args and result plain
  JSON data, progress(x) a number (frames, simulated seconds). Locally it runs on a worker process (`python -m
  drivestudio.pool worker`) that takes one job after another as a JSON line on stdin and answers with JSON lines on
  stdout: {"progress": x} any number of times, then {"done": result} or {"error": line}. Pipes, not
  multiprocessing: nothing is left in /dev/shm when a run is killed. On Ray it is one task of one CPU, retried twice
  if its worker dies; the progress it reported is handed on when it ends.
- a command, `Job(name, argv=[...], log=PATH)`: `python -m drivestudio ARGV` (or the pool's `command` + ARGV) as a
  process of its own, stdout and stderr into `log` (None: this process's), succeeding with exit status 0. On Ray a
  task runs that process on its node, in this process's folder (which, like the log's, must then be a path every
  node shares).

A job with `after` starts once those jobs of the run have succeeded (a name not in the run succeeded before it);
a free slot takes the first job of the list that may start (Ray: every such job is sent at once, and the cluster's
CPUs decide how many run). A job that fails ends the run with JobFailed (a RunError: one line, exit status 1) once
the others are stopped, or with `finish`, once the running ones have finished (nothing new starts). Ctrl-C and
SIGTERM stop every job. Every local process is started through core.children.popen, so it dies with this process
however this one ends (kill -9 included); a Ray task's process dies with the Ray worker that runs it.

    Pool(slots=2, env=ONE_THREAD).run(jobs, on_progress=bar.update, on_done=results.append)
"""
from __future__ import annotations

import importlib
import json
import os
import re
import selectors
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

from core.children import die_with_parent, popen
from core.signals import exit_on_sigterm
from drivestudio.errors import RunError, UsageError

BACKENDS = ("local", "ray")
# a child that leaves the other cores to its siblings (the recipe's trainings, the benchmark's route workers)
ONE_THREAD = {"OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}
_COUNT = re.compile(rb"(\d+)/(\d+) \[")


@dataclass
class Job:
    name: str                        # names it in messages and in other jobs' `after`
    argv: list | None = None         # a command's arguments, run as a process of its own
    after: tuple = ()                # names of the jobs that must succeed first
    log: Path | None = None          # a command's output (None: this process's)
    call: str | None = None          # or: "module:function", run with (args, progress) on a worker
    args: dict = field(default_factory=dict)


class JobFailed(RunError):
    """The jobs that failed (the first one's reason is the message); `status`: the first one's exit status, for a
    command."""

    def __init__(self, message: str, jobs: list[Job], status: int | None = None):
        super().__init__(message)
        self.jobs, self.status = jobs, status


def progress(log: Path) -> str:
    """The last `done/total` a tqdm bar wrote to `log` ('-' before the first)."""
    try:
        with open(log, "rb") as f:
            f.seek(max(0, f.seek(0, os.SEEK_END) - 4096))
            found = _COUNT.findall(f.read())
    except OSError:
        return "-"
    return f"{int(found[-1][0])}/{int(found[-1][1])}" if found else "-"


def last_line(log: Path | None) -> str:
    try:
        text = log.read_text(errors="replace") if log is not None else ""
    except OSError:
        return ""
    lines = [ln.strip() for ln in text.replace("\r", "\n").splitlines() if ln.strip()]
    return lines[-1] if lines else ""


def _command_failed(job: Job, status: int) -> JobFailed:
    if job.log is None:
        return JobFailed(f"{job.name}: exit status {status}", [job], status)
    return JobFailed(f"{job.log.name}: exit status {status}: {last_line(job.log)}", [job], status)


def _function(ref: str) -> Callable:
    module, _, name = ref.partition(":")
    return getattr(importlib.import_module(module), name)


class Pool:
    """Runs lists of jobs on `slots` local processes at a time, or as Ray tasks. `env`: added to every job's
    environment. `stop_wait`: the seconds a local process told to stop (SIGTERM) has to unwind before it is killed
    (0: killed at once). `command`: what a command job's argv follows (default: this Python's drivestudio)."""

    def __init__(self, backend: str = "local", slots: int = 1, env: dict | None = None, stop_wait: float = 30.0,
                 finish: bool = False, command: tuple | None = None, every: float | None = None):
        if backend not in BACKENDS:
            raise UsageError(f"--backend: {backend!r} is not one of {', '.join(BACKENDS)}")
        self.backend, self.slots, self.env, self.stop_wait = backend, max(1, slots), dict(env or {}), stop_wait
        self.finish, self.command, self.every = finish, command, every

    def run(self, jobs: list[Job], on_progress: Callable | None = None, on_done: Callable | None = None,
            on_start: Callable[[Job], object] | None = None) -> None:
        """Run every job: on_start(job) as each starts, on_progress(x) for a call's progress, on_done(result) for
        each call that ends; returns when all have succeeded, raises JobFailed otherwise."""
        names = [j.name for j in jobs]
        if len(set(names)) != len(names):
            raise ValueError("two jobs of one name")
        if any(a in names[i:] for i, j in enumerate(jobs) for a in j.after):
            raise ValueError("each job after an earlier one")
        waiting, succeeded = list(jobs), set()
        failed: list[JobFailed] = []
        started: set[str] = set()
        runner = _Local(self) if self.backend == "local" else _Ray(self)
        t0 = shown = time.perf_counter()
        with exit_on_sigterm():   # a run stopped by SIGTERM stops its jobs (the finally below)
            try:
                runner.open()
                while True:
                    while not failed and runner.free():
                        job = next((j for j in waiting
                                    if all(a in succeeded or a not in names for a in j.after)), None)
                        if job is None:
                            break
                        waiting.remove(job)
                        started.add(job.name)
                        if on_start is not None:
                            on_start(job)
                        runner.start(job)
                    if not runner.busy():
                        break
                    for kind, job, value in runner.events(timeout=1.0):
                        if kind == "progress" and on_progress is not None:
                            on_progress(value)
                        elif kind == "done":
                            succeeded.add(job.name)
                            if on_done is not None and job.call is not None:
                                on_done(value)
                        elif kind == "failed":
                            failed.append(value)
                            if not self.finish:
                                raise value
                    if self.every is not None and time.perf_counter() - shown >= self.every:
                        shown = time.perf_counter()
                        print(f"  {(shown - t0) / 60:5.1f} min: " + ", ".join(
                            (progress(j.log) if j.log is not None else "-") if j.name in started else "waiting"
                            for j in jobs), flush=True)
                if failed:
                    raise JobFailed(str(failed[0]), [j for f in failed for j in f.jobs], failed[0].status)
                if waiting:
                    raise RunError(f"{waiting[0].name} waits for jobs that never run: {', '.join(waiting[0].after)}")
                runner.close()
            finally:
                runner.stop()


def run_verb(argv: list) -> None:
    """A verb as a process of its own (a step of the recipe or the study), its output this process's; its failure,
    whose one line it wrote to stderr itself, ends this process with its exit status."""
    try:
        Pool().run([Job(str(argv[0]), argv=[str(a) for a in argv])])
    except JobFailed as e:
        raise SystemExit(e.status or 1) from None


# --- local processes -----------------------------------------------------------------------------------------
class _Local:
    """Calls on worker processes (each takes the next call when it is done), commands as processes of their own;
    `slots` of them busy at a time."""

    def __init__(self, pool: Pool):
        self.pool = pool
        self.env = dict(os.environ, PYTHONUNBUFFERED="1", **pool.env)
        self.workers: list[subprocess.Popen] = []         # call workers, busy or idle
        self.busy_on: dict[subprocess.Popen, Job] = {}    # what each busy process (worker or command) runs
        self.pending: dict[subprocess.Popen, bytes] = {}  # bytes read from a worker that do not yet end a line
        self.sel = selectors.DefaultSelector()

    def open(self) -> None:
        pass

    def busy(self) -> bool:
        return bool(self.busy_on)

    def free(self) -> bool:
        return len(self.busy_on) < self.pool.slots

    def start(self, job: Job) -> None:
        if job.call is None:
            command = list(self.pool.command or (sys.executable, "-m", "drivestudio"))
            if job.log is None:
                proc = popen([*command, *map(str, job.argv or [])], env=self.env)
            else:
                with open(job.log, "ab") as out:
                    proc = popen([*command, *map(str, job.argv or [])], stdout=out, stderr=subprocess.STDOUT,
                                 env=self.env)
            self.busy_on[proc] = job
            return
        worker = next((w for w in self.workers if w not in self.busy_on), None)
        if worker is None:
            worker = popen([sys.executable, "-m", "drivestudio.pool", "worker"], stdin=subprocess.PIPE,
                           stdout=subprocess.PIPE, env=self.env, cwd=os.getcwd())
            assert worker.stdout is not None   # started with stdout=PIPE
            self.workers.append(worker)
            self.pending[worker] = b""
            self.sel.register(worker.stdout, selectors.EVENT_READ, worker)
        assert worker.stdin is not None
        worker.stdin.write((json.dumps({"call": job.call, "args": job.args}) + "\n").encode())
        worker.stdin.flush()
        self.busy_on[worker] = job

    def events(self, timeout: float) -> Iterator[tuple]:
        if self.sel.get_map():
            ready = self.sel.select(timeout=timeout)
        else:
            time.sleep(timeout)
            ready = []
        for key, _ in ready:
            yield from self._read(key.data)
        for proc, job in list(self.busy_on.items()):
            if job.call is None and proc.poll() is not None:
                del self.busy_on[proc]
                yield ("done", job, None) if proc.returncode == 0 else ("failed", job,
                                                                         _command_failed(job, proc.returncode))

    def _read(self, worker: subprocess.Popen) -> Iterator[tuple]:
        """What a worker has written, line by line; a death in the middle of a job fails it."""
        assert worker.stdout is not None
        chunk = os.read(worker.stdout.fileno(), 1 << 16)   # raw reads: no line may hide in a buffer
        if not chunk:
            self.sel.unregister(worker.stdout)
            job = self.busy_on.pop(worker, None)
            if job is not None:
                yield "failed", job, JobFailed(f"a worker died on {job.name} (exit status {worker.wait()})", [job])
            return
        *lines, self.pending[worker] = (self.pending[worker] + chunk).split(b"\n")
        for line in lines:
            msg = json.loads(line)
            job = self.busy_on[worker]
            if "progress" in msg:
                yield "progress", job, msg["progress"]
            elif "done" in msg:
                del self.busy_on[worker]
                yield "done", job, msg["done"]
            else:
                del self.busy_on[worker]
                yield "failed", job, JobFailed(msg.get("error", f"{job.name} failed"), [job])

    def close(self) -> None:
        """The idle workers told that no job is left (end of input); they exit."""
        for w in self.workers:
            assert w.stdin is not None
            w.stdin.close()
        for w in self.workers:
            w.wait(timeout=30)

    def stop(self) -> None:
        """Processes still running get SIGTERM and `stop_wait` seconds (0: killed at once); all are waited for."""
        procs = self.workers + [p for p in self.busy_on if p not in self.workers]
        for p in procs:
            if p.poll() is None:
                p.terminate() if self.pool.stop_wait > 0 else p.kill()
        for p in procs:
            try:
                p.wait(timeout=self.pool.stop_wait or None)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        self.sel.close()


def serve() -> int:
    """A local worker: every call read from stdin run in turn, its progress, result or error written to stdout.
    Returns the exit status."""
    die_with_parent()   # also when started by another program than the pool
    if os.getppid() == 1:
        return 1
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C reaches the whole group: the parent stops us
    out_stream = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)   # library chatter must not corrupt the protocol

    def send(obj) -> None:
        out_stream.write(json.dumps(obj) + "\n")

    with exit_on_sigterm():   # SIGTERM from the parent unwinds: worlds, bridges and half-written files are closed
        for line in sys.stdin:
            job = json.loads(line)
            try:
                send({"done": _function(job["call"])(job["args"], lambda x: send({"progress": x}))})
            except Exception as e:  # the parent reports it in one line and stops the run
                send({"error": f"{_name_of(job)}: {type(e).__name__}: {e}"})
    return 0


def _name_of(job: dict) -> str:
    """How a call's error line names it: its function's `job_name(args)` when the module has one."""
    module, _, _ = job["call"].partition(":")
    name = getattr(importlib.import_module(module), "job_name", None)
    return name(job["args"]) if name is not None else job["call"]


# --- Ray -----------------------------------------------------------------------------------------------------
def ray_call(call: str, args: dict, cwd: str) -> dict:
    """A Ray task: one call on whichever node runs it (module level, so that the workers import it by reference),
    in this process's folder where the node has it (relative paths then mean the same), with the progress it
    reported."""
    reported: list = []
    before = os.getcwd()
    if os.path.isdir(cwd):
        os.chdir(cwd)
    try:
        result = _function(call)(args, reported.append)
    finally:
        os.chdir(before)
    return {"result": result, "progress": reported}


def ray_command(command: list, argv: list, log: str | None, env: dict, cwd: str) -> int:
    """A Ray task: a command as a process of its own on whichever node runs it; returns its exit status."""
    command = command or [sys.executable, "-m", "drivestudio"]
    args = [*command, *map(str, argv)]
    environ = os.environ | env
    where = cwd if os.path.isdir(cwd) else None
    if log is None:
        return popen(args, env=environ, cwd=where).wait()
    with open(log, "ab") as out:
        return popen(args, stdout=out, stderr=subprocess.STDOUT, env=environ, cwd=where).wait()


def check_reachable(address: str | None, timeout: float = 10.0) -> None:
    """RAY_ADDRESS=host:port (or ray://host:port) must answer: ray.init would otherwise retry for minutes."""
    if not address or address == "auto":
        return
    host, _, port = address.split("://")[-1].rpartition(":")
    if not host or not port.isdigit():
        return
    try:
        socket.create_connection((host, int(port)), timeout=timeout).close()
    except OSError as e:
        raise RunError(f"--backend ray: no Ray cluster answers at RAY_ADDRESS={address} ({e.strerror or e}); start "
                       "one with `ray start --head` (docs/scaling.md)") from None


class _Ray:
    """Every job that may start is a Ray task at once: the cluster's CPUs decide how many run."""

    def __init__(self, pool: Pool):
        self.pool = pool
        self.pending: dict = {}   # task reference -> job
        self.started = False

    def open(self) -> None:
        try:
            import ray  # lazy: an optional extra, seconds to import; without it, one clear line
        except ImportError:
            raise UsageError("--backend ray needs Ray: pip install 'drivestudio[cluster]' (and a folder every node "
                             "can write to as --out)") from None
        self.ray = ray
        address = os.environ.get("RAY_ADDRESS")
        check_reachable(address)
        env_vars = {k: os.environ[k] for k in ("DRIVESTUDIO_WORLDS",) if os.environ.get(k)}
        self.started = not ray.is_initialized()
        try:
            ray.init(address=address, ignore_reinit_error=True, log_to_driver=False,
                     runtime_env={"env_vars": env_vars} if env_vars else None)
        except (ConnectionError, RuntimeError, ValueError) as e:
            self.started = False
            raise RunError(f"--backend ray: cannot reach the Ray cluster at {address or '(a new local one)'}: "
                           f"{str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__}") from None
        self.call = ray.remote(num_cpus=1, max_retries=2)(ray_call)
        self.command = ray.remote(num_cpus=1, max_retries=0)(ray_command)

    def busy(self) -> bool:
        return bool(self.pending)

    def free(self) -> bool:
        return True

    def start(self, job: Job) -> None:
        ref: object
        if job.call is not None:
            ref = self.call.remote(job.call, job.args, os.getcwd())
        else:
            ref = self.command.remote(list(self.pool.command or []), list(job.argv or []),
                                      str(Path(job.log).resolve()) if job.log is not None else None, self.pool.env,
                                      os.getcwd())
        self.pending[ref] = job

    def events(self, timeout: float) -> Iterator[tuple]:
        done, _ = self.ray.wait(list(self.pending), num_returns=1, timeout=timeout)
        for ref in done:
            job = self.pending.pop(ref)
            try:
                value = self.ray.get(ref)
            except self.ray.exceptions.RayError as e:
                cause = getattr(e, "cause", None) or e
                text = str(cause).strip()
                yield "failed", job, JobFailed(f"{job.name} failed on the Ray cluster: {type(cause).__name__}: "
                                               f"{text.splitlines()[-1] if text else ''}", [job])
                continue
            if job.call is None:
                yield ("done", job, None) if value == 0 else ("failed", job, _command_failed(job, value))
                continue
            for x in value["progress"]:
                yield "progress", job, x
            yield "done", job, value["result"]

    def close(self) -> None:
        pass

    def stop(self) -> None:
        for ref in self.pending:
            self.ray.cancel(ref, force=True)
        if self.started:
            self.ray.shutdown()


if __name__ == "__main__":
    if sys.argv[1:] == ["worker"]:
        sys.exit(serve())
    sys.exit("usage: python -m drivestudio.pool worker (started by a pool of `drivestudio`)")
