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

import ctypes
import json
import os
import selectors
import signal
import subprocess
import sys
from collections.abc import Callable

from drivestudio.errors import RunError


def _die_with_parent() -> None:
    try:  # PR_SET_PDEATHSIG: a SIGKILLed parent takes its workers with it rather than leave them running
        ctypes.CDLL(None).prctl(1, signal.SIGKILL)
    except (OSError, AttributeError):
        pass


def serve(run_one: Callable[[dict, Callable], dict], what: Callable[[dict], str]) -> int:
    """The worker's side: run_one(job, progress) for every job read from stdin; `what(job)` names a job in an
    error line. Returns the exit status."""
    _die_with_parent()
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
    procs = [subprocess.Popen([sys.executable, "-m", module, "worker"], stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, env=env, cwd=os.getcwd())
             for _ in range(max(1, min(workers, len(jobs))))]
    queue = list(jobs)
    busy: dict = {}
    pending: dict = {p: b"" for p in procs}   # bytes read from a worker that do not yet end in a newline
    sel = selectors.DefaultSelector()

    def give(proc) -> None:
        if queue:
            job = queue.pop(0)
            proc.stdin.write((json.dumps(job) + "\n").encode())
            proc.stdin.flush()
            busy[proc] = job
        else:
            proc.stdin.close()

    def handle(proc, line: bytes) -> None:
        msg = json.loads(line)
        if "progress" in msg:
            on_progress(msg["progress"])
        elif "done" in msg:
            busy.pop(proc)
            on_done(msg["done"])
            give(proc)
        else:
            raise RunError(msg.get("error", "a worker failed"))

    try:
        for p in procs:
            assert p.stdout is not None   # started with stdout=PIPE
            sel.register(p.stdout, selectors.EVENT_READ, p)
            give(p)
        while busy:
            for key, _ in sel.select(timeout=1.0):
                proc = key.data
                chunk = os.read(proc.stdout.fileno(), 1 << 16)   # raw reads: no line may hide in a buffer
                if not chunk:
                    sel.unregister(proc.stdout)
                    if proc in busy:
                        raise RunError(f"a worker died on {what(busy[proc])} (exit status {proc.wait()})")
                    continue
                *lines, pending[proc] = (pending[proc] + chunk).split(b"\n")
                for line in lines:
                    handle(proc, line)
        for p in procs:
            p.wait(timeout=30)
    finally:
        for p in procs:
            if p.poll() is None:
                p.terminate() if stop_wait > 0 else p.kill()
        for p in procs:
            try:
                p.wait(timeout=stop_wait or None)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        sel.close()
