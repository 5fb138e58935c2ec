"""A SUMO road network for any track, built with SUMO's own netconvert and cached per track.

The loop is cut into a few edges whose shapes follow the track's centreline (spreadType="center"), with one
lane per track lane, so SUMO's lane centres lie on ours (within a centimetre). Lane i of SUMO counts from
the right; our lane k counts from the left: i = N - 1 - k. Internal junction links are left out, so a car
runs straight from the end of one edge onto the same lane of the next and round the loop.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.highway.errors import TrafficError
from sim.track import Track

GENERATOR_VERSION = 2      # bump when the network's construction changes, to invalidate caches
EDGE_LENGTH = 250.0        # [m] target length of one SUMO edge
SHAPE_STEP = 2.0           # [m] centreline sampling of edge shapes
SPEED_LIMIT = 30.0         # [m/s] lane speed limit; AI cars' desired speeds are fractions of it
NETCONVERT_TIMEOUT = 120.0  # [s]


@dataclass(frozen=True)
class SumoNetwork:
    path: Path                 # the .net.xml
    edges: tuple[str, ...]     # edge ids in driving order, edges[0] starts at s = 0
    starts: tuple[float, ...]  # s [m] at the start of each edge


def cache_dir() -> Path:
    root = os.environ.get("DRIVESTUDIO_CACHE") or Path.home() / ".cache" / "drivestudio"
    return Path(root) / "sumo"


def _sumo_version() -> str:
    try:
        import sumolib  # lazy: 0.1 s to import, and only a world with AI cars needs SUMO
        return str(getattr(sumolib, "__version__", "")) or _netconvert()
    except ImportError:  # pragma: no cover - sumolib is a declared dependency
        return _netconvert()


def _netconvert() -> str:
    try:
        import sumo  # lazy: as sumolib; and a missing SUMO is one clear TrafficError, not an ImportError
    except ImportError:
        raise TrafficError("SUMO is not installed (the eclipse-sumo package provides netconvert)") from None
    exe = Path(sumo.SUMO_HOME) / "bin" / "netconvert"
    if not exe.is_file():
        raise TrafficError(f"netconvert not found at {exe}")
    return str(exe)


def _edge_bounds(track: Track) -> np.ndarray:
    """Edges start at every segment boundary (so an edge is all straight or all arc, and a lane position maps
    to s by one ratio) and are cut to at most EDGE_LENGTH; a loop needs at least three edges."""
    starts: list[float] = []
    for seg, s0 in zip(track.segments, track.starts):
        n = max(1, int(math.ceil(seg.length / EDGE_LENGTH)))
        starts.extend(s0 + seg.length * np.arange(n) / n)
    bounds = np.array(starts)
    while len(bounds) < 3:  # halve every edge
        bounds = np.sort(np.r_[bounds, (bounds + np.r_[bounds[1:], track.length]) / 2])
    return np.r_[bounds, track.length]


def _plain_xml(track: Track, bounds: np.ndarray, where: Path) -> None:
    n = len(bounds) - 1
    nodes = ["<nodes>"]
    for i in range(n):
        x, y, _ = track.pose(bounds[i])
        nodes.append(f'  <node id="n{i}" x="{x:.4f}" y="{y:.4f}" type="priority"/>')
    nodes.append("</nodes>")
    edges = ["<edges>"]
    for i in range(n):
        a, b = bounds[i], bounds[i + 1]
        s = np.unique(np.r_[np.arange(a, b, SHAPE_STEP), b])
        x, y, _ = track.pose(s)  # s = length wraps to 0: the last edge ends exactly on the first node
        shape = " ".join(f"{u:.4f},{v:.4f}" for u, v in zip(x, y))
        edges.append(f'  <edge id="e{i}" from="n{i}" to="n{(i + 1) % n}" numLanes="{track.lanes}" '
                     f'width="{track.lane_width}" speed="{SPEED_LIMIT}" spreadType="center" shape="{shape}"/>')
    edges.append("</edges>")
    cons = ["<connections>"]
    for i in range(n):
        for lane in range(track.lanes):
            cons.append(f'  <connection from="e{i}" to="e{(i + 1) % n}" fromLane="{lane}" toLane="{lane}"/>')
    cons.append("</connections>")
    (where / "loop.nod.xml").write_text("\n".join(nodes) + "\n")
    (where / "loop.edg.xml").write_text("\n".join(edges) + "\n")
    (where / "loop.con.xml").write_text("\n".join(cons) + "\n")


def network_for(track: Track) -> SumoNetwork:
    """The SUMO network of `track`, from the cache or built now (about half a second)."""
    bounds = _edge_bounds(track)
    key = hashlib.sha256(json.dumps({"spec": track.spec.get("segments"), "lanes": track.lanes,
                                     "lane_width": track.lane_width, "generator": GENERATOR_VERSION,
                                     "sumo": _sumo_version()}, sort_keys=True).encode()).hexdigest()[:20]
    final = cache_dir() / key
    net = SumoNetwork(final / "loop.net.xml", tuple(f"e{i}" for i in range(len(bounds) - 1)),
                      tuple(float(b) for b in bounds[:-1]))
    if net.path.is_file():
        return net
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{key}.", dir=final.parent))
    try:
        _plain_xml(track, bounds, tmp)
        cmd = [_netconvert(), "-n", "loop.nod.xml", "-e", "loop.edg.xml", "-x", "loop.con.xml",
               "-o", "loop.net.xml", "--no-internal-links", "true", "--no-turnarounds", "true",
               "--offset.disable-normalization", "true", "--geometry.remove", "false", "--no-warnings", "true"]
        try:
            proc = subprocess.run(cmd, cwd=tmp, capture_output=True, text=True, timeout=NETCONVERT_TIMEOUT)
        except subprocess.TimeoutExpired:
            raise TrafficError(f"netconvert took longer than {NETCONVERT_TIMEOUT:.0f} s on track "
                               f"'{track.name}'") from None
        if proc.returncode != 0 or not (tmp / "loop.net.xml").is_file():
            last = (proc.stderr.strip().splitlines() or ["no output"])[-1]
            raise TrafficError(f"SUMO cannot build a network for track '{track.name}': {last}")
        try:
            os.replace(tmp, final)
        except OSError:  # another process cached it first
            if not net.path.is_file():
                raise
        return net
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
