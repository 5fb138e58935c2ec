"""Which SUMO a SumoTraffic talks to: the only module that imports libsumo and traci.

libsumo runs SUMO inside this process, the fastest way (no socket, no second process), but it holds one
simulation per process. So the first traffic of a process gets libsumo, and every other one open at the same
time gets its own `sumo` process (the binary the eclipse-sumo package ships) driven over TraCI, a socket on
localhost. Both speak the same API (`conn.vehicle.add`, `conn.simulationStep`, ...), so SumoTraffic does not
know which it has; the same command line gives the same traffic either way (tests/sim/test_sumo_transports.py).

A TraCI process is ended when its traffic closes, when its traffic is garbage-collected and at interpreter exit
(weakref.finalize), so no `sumo` process outlives its world.
"""
from __future__ import annotations

import os
import socket
import subprocess
import tempfile
import time
import weakref
from pathlib import Path
from typing import Any

import numpy as np

from core.children import popen
from sim.highway.errors import TrafficError

TRANSPORTS = ("auto", "libsumo", "traci")
CONNECT_TIMEOUT = 60.0   # [s] for a sumo process to load its network and listen
CONNECT_POLL = 0.01      # [s] between attempts: a small network loads in about 50 ms
PORT_TRIES = 5           # another program may take the free port we picked before sumo binds it

_libsumo_busy = False   # a SumoConnection holds libsumo now


def _load_libsumo():
    try:
        import libsumo  # lazy: libsumo takes 0.65 s to import and only a world with AI cars needs it
    except ImportError as e:  # pragma: no cover - libsumo is a declared dependency
        raise TrafficError(f"libsumo cannot be loaded: {e}") from None
    return libsumo


def sumo_binary() -> str:
    """The `sumo` executable of the installed eclipse-sumo package (nothing is downloaded)."""
    try:
        import sumo  # lazy: only a second world in one process needs the binary
    except ImportError:  # pragma: no cover - eclipse-sumo is a declared dependency
        raise TrafficError("SUMO is not installed (the eclipse-sumo package provides the sumo binary)") from None
    exe = Path(sumo.SUMO_HOME) / "bin" / "sumo"
    if not exe.is_file():
        raise TrafficError(f"the sumo binary is not found at {exe}")
    return str(exe)


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("localhost", 0))
        return int(s.getsockname()[1])


def _end_process(conn, proc: subprocess.Popen, owner: int) -> None:
    """Close the TraCI connection (sumo then exits by itself); kill sumo if it does not. Runs once: at close,
    at garbage collection or at interpreter exit, whichever comes first; and only in the process that started it
    (a forked child, an async vector env's worker, must not close its parent's socket)."""
    if os.getpid() != owner:
        return
    try:
        conn.close(wait=False)
    except Exception:   # a sumo that died already: nothing to say goodbye to
        pass
    try:
        proc.wait(timeout=5)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


def _end_libsumo(api, owner: int) -> None:
    """Close libsumo's simulation and free the slot. Runs once, as _end_process, in the process that started it."""
    global _libsumo_busy
    if os.getpid() != owner:
        return
    try:
        api.close()
    except Exception:   # libsumo raises when SUMO already ended; closing is all we wanted
        pass
    _libsumo_busy = False


class SumoConnection:
    """One running SUMO simulation: `api` is the libsumo module or a TraCI connection (the same methods);
    `transport` says which ("libsumo" or "traci"), `pid` the sumo process's id (None with libsumo)."""

    def __init__(self, args: list[str], transport: str = "auto"):
        global _libsumo_busy
        if transport not in TRANSPORTS:
            raise TrafficError(f"unknown SUMO transport {transport!r} (choose from {', '.join(TRANSPORTS)})")
        self.transport = transport
        if transport == "auto":
            self.transport = "traci" if _libsumo_busy else "libsumo"
        self.pid: int | None = None
        self._subscribed: set[str] = set()
        self._finalizer: weakref.finalize[..., Any]
        if self.transport == "libsumo":
            if _libsumo_busy:
                raise TrafficError("libsumo already runs a simulation in this process (one at a time); "
                                   "use the traci transport for another")
            self.api = _load_libsumo()
            self.api.start(args)   # raises on a bad command line; nothing is held then
            _libsumo_busy = True
            self._finalizer = weakref.finalize(self, _end_libsumo, self.api, os.getpid())
        else:
            self.api, proc = self._start_process(args)
            self._finalizer = weakref.finalize(self, _end_process, self.api, proc, os.getpid())
            self.pid = proc.pid

    @staticmethod
    def _start_process(args: list[str]):
        import traci  # lazy: only a second world in one process needs TraCI
        exe = sumo_binary()
        last = "no output"
        for _ in range(PORT_TRIES):
            port = _free_port()
            with tempfile.TemporaryFile() as err:
                proc = popen([exe, *args[1:], "--remote-port", str(port)], stdin=subprocess.DEVNULL,
                             stdout=subprocess.DEVNULL, stderr=err)
                deadline = time.monotonic() + CONNECT_TIMEOUT
                while True:
                    try:
                        # numRetries=0: one attempt, no message on stdout; we poll here instead of traci's 1 s sleeps
                        return traci.connect(port, numRetries=0, proc=proc), proc
                    except Exception:
                        if proc.poll() is not None or time.monotonic() > deadline:
                            break
                        time.sleep(CONNECT_POLL)
                if proc.poll() is None:   # never listened in time
                    proc.kill()
                proc.wait()
                err.seek(0)
                last = ([ln for ln in err.read().decode(errors="replace").splitlines() if ln.strip()]
                        or [f"sumo exited with status {proc.returncode}"])[-1]
                if "port" not in last.lower() and "address" not in last.lower():
                    break   # not a port taken by someone else: another port will not help
        raise TrafficError(f"the sumo process did not start: {last}")

    def close(self) -> None:
        self._finalizer()   # idempotent: a finalizer runs at most once

    def car_readings(self, ids: list[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(front bumper positions (n, 2), compass angles [deg], speeds [m/s]) of vehicles `ids`, all present.
        Over TraCI each getter is a socket round trip (36 for 12 cars), so these come by subscription: SUMO sends
        every subscribed value with its step's answer, and a car is subscribed once, when first read. libsumo's
        getters are plain calls, cheaper than subscriptions' bookkeeping: it reads them one by one."""
        v = self.api.vehicle
        if self.transport == "libsumo":
            return (np.array([v.getPosition(i) for i in ids]), np.array([v.getAngle(i) for i in ids]),
                    np.array([v.getSpeed(i) for i in ids]))
        import traci.constants as tc  # lazy, as traci
        for i in ids:
            if i not in self._subscribed:
                v.subscribe(i, (tc.VAR_POSITION, tc.VAR_ANGLE, tc.VAR_SPEED))
                self._subscribed.add(i)
        got = v.getAllSubscriptionResults()
        return (np.array([got[i][tc.VAR_POSITION] for i in ids]), np.array([got[i][tc.VAR_ANGLE] for i in ids]),
                np.array([got[i][tc.VAR_SPEED] for i in ids]))


def libsumo_free() -> bool:
    """Whether the next "auto" connection gets libsumo."""
    return not _libsumo_busy
