"""Local worker processes fed JSON jobs over pipes: the parallelism of `generate` and `benchmark`.

The parent starts `python -m MODULE worker` processes, writes one job (a JSON line) to a worker's stdin, and reads
JSON lines back from its stdout: {"progress": x} any number of times, then {"done": result} or {"error": line}.
A worker that finishes a job gets the next; when the queue is empty its stdin is closed and it exits. Pipes, not
multiprocessing: nothing is left in /dev/shm when a run is killed (multiprocessing's semaphores were), and a
worker dies with its parent (PR_SET_PDEATHSIG).

    parent:  run_pool("drivestudio.generate", jobs, workers, on_progress, on_done, what=lambda job: "...")
    worker:  return serve(lambda job, progress: ..., what=lambda job: "...")
"""
from __future__ import annotations

import json
import os
import selectors
import signal
import subprocess
import sys
from collections.abc import Callable

from core.children import die_with_parent, popen
from drivestudio.errors import RunError


def serve(run_one: Callable[[dict, Callable], dict], what: Callable[[dict], str]) -> int:
    """The worker's side: run_one(job, progress) for every job read from stdin; `what(job)` names a job in an
    error line. Returns the exit status."""
    die_with_parent()   # also when started by another program than run_pool
    if os.getppid() == 1:
        return 1
    signal.signal(signal.SIGINT, signal.SIG_IGN)   # Ctrl-C reaches the whole group: the parent stops us
    out_stream = os.fdopen(os.dup(1), "w", buffering=1)
    os.dup2(os.open(os.devnull, os.O_WRONLY), 1)   # library chatter must not corrupt the protocol

    def send(obj) -> None:
        out_stream.write(json.dumps(obj) + "\n")

    for line in sys.stdin:
        job = json.loads(line)
        try:
            send({"done": run_one(job, lambda x: send({"progress": x}))})
        except Exception as e:  # the parent reports it in one line and stops the run
            send({"error": f"{what(job)}: {type(e).__name__}: {e}"})
    return 0


def run_pool(module: str, jobs: list[dict], workers: int, on_progress: Callable, on_done: Callable,
             what: Callable[[dict], str], env: dict | None = None, stop_wait: float = 0.0) -> None:
    """Run `jobs` on up to `workers` processes of `python -m module worker`, in order; on_progress(x) for each
    progress message, on_done(result) for each finished job. A worker's error line or death raises RunError (its
    job named by `what`). On the way out, workers still running get SIGTERM and `stop_wait` seconds to unwind
    (0: they are killed at once)."""
    env = dict(os.environ, PYTHONUNBUFFERED="1", **(env or {}))
    procs = [popen([sys.executable, "-m", module, "worker"], stdin=subprocess.PIPE, stdout=subprocess.PIPE, env=env,
                   cwd=os.getcwd())
             for _ in range(max(1, min(workers, len(jobs))))]
    pool = _Pool(procs, jobs, on_progress, on_done, what)
    try:
        pool.run()
        for p in procs:
            p.wait(timeout=30)
    finally:
        _stop(procs, stop_wait)
        pool.sel.close()


class _Pool:
    """The parent's side of one run: the jobs still queued, the job each worker is on, and the bytes read from
    each worker that do not yet end in a newline."""

    def __init__(self, procs: list, jobs: list[dict], on_progress: Callable, on_done: Callable,
                 what: Callable[[dict], str]):
        self.procs, self.on_progress, self.on_done, self.what = procs, on_progress, on_done, what
        self.queue = list(jobs)
        self.busy: dict = {}
        self.pending: dict = {p: b"" for p in procs}
        self.sel = selectors.DefaultSelector()

    def give(self, proc) -> None:
        """The next job to a worker that is free, or end of input when none is left."""
        if self.queue:
            job = self.queue.pop(0)
            proc.stdin.write((json.dumps(job) + "\n").encode())
            proc.stdin.flush()
            self.busy[proc] = job
        else:
            proc.stdin.close()

    def handle(self, proc, line: bytes) -> None:
        """One message of a worker: progress, a finished job (then the next job), or an error."""
        msg = json.loads(line)
        if "progress" in msg:
            self.on_progress(msg["progress"])
        elif "done" in msg:
            self.busy.pop(proc)
            self.on_done(msg["done"])
            self.give(proc)
        else:
            raise RunError(msg.get("error", "a worker failed"))

    def read(self, proc) -> None:
        """What a worker has written: its whole lines handled, a death in the middle of a job raised."""
        chunk = os.read(proc.stdout.fileno(), 1 << 16)   # raw reads: no line may hide in a buffer
        if not chunk:
            self.sel.unregister(proc.stdout)
            if proc in self.busy:
                raise RunError(f"a worker died on {self.what(self.busy[proc])} (exit status {proc.wait()})")
            return
        *lines, self.pending[proc] = (self.pending[proc] + chunk).split(b"\n")
        for line in lines:
            self.handle(proc, line)

    def run(self) -> None:
        """A job to every worker, then theirs as they finish, until no job is left running."""
        for p in self.procs:
            assert p.stdout is not None   # started with stdout=PIPE
            self.sel.register(p.stdout, selectors.EVENT_READ, p)
            self.give(p)
        while self.busy:
            for key, _ in self.sel.select(timeout=1.0):
                self.read(key.data)


def _stop(procs: list, stop_wait: float) -> None:
    """Workers still running get SIGTERM and `stop_wait` seconds (0: killed at once); all are waited for."""
    for p in procs:
        if p.poll() is None:
            p.terminate() if stop_wait > 0 else p.kill()
    for p in procs:
        try:
            p.wait(timeout=stop_wait or None)
        except subprocess.TimeoutExpired:
            p.kill()
            p.wait()
