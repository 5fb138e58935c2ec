"""A closed-loop track: a centreline made of segments and a cross-section of N lanes.

Conventions (docs/affordances.md): s [m] is arc length along the centreline in the driving direction,
0 <= s < length, s = 0 at the start of the first segment, which heads along +x from the origin.
d [m] is the lateral offset from the centreline, positive to the left. Lane k = 0..N-1 counts from the
left; marking j = 0..N from the left edge to the right edge.
"""
from __future__ import annotations

import bisect
import math
from dataclasses import dataclass, field

import numpy as np

from core.worlds.highway import lane_centres, markings
from sim.track.segments import Arc, Segment, wrap_angle

VERGE_WIDTH = 2.0  # [m] shoulder beside each edge; the on-marking system covers it (docs/affordances.md)


@dataclass
class Track:
    name: str
    segments: list[Segment]
    lanes: int
    lane_width: float = 4.0  # [m]
    spec: dict = field(default_factory=dict, repr=False)  # the JSON form it was built from

    def __post_init__(self):
        lengths = np.array([seg.length for seg in self.segments])
        self.starts = np.concatenate([[0.0], np.cumsum(lengths)[:-1]])  # [m] s at each segment's start
        self.length = float(lengths.sum())                               # [m]
        n, w = self.lanes, self.lane_width
        self.markings = markings(n, w)                                    # [m] m_j, left edge first
        self.lane_centres = lane_centres(n, w)                            # [m] c_k, leftmost first
        self.half_width = n * w / 2                                      # [m] centreline to an edge
        self._fast_straight = self._straight_runs()
        self._kappa = np.array([seg.curvature for seg in self.segments])
        self._starts_list = self.starts.tolist()  # for bisect: the scalar path of the hot loops

    # --- arc length -----------------------------------------------------------------------------------
    def wrap_s(self, s):
        """s [m] wrapped into [0, length)."""
        if isinstance(s, (float, int)):
            return float(s) % self.length
        return np.mod(s, self.length) if np.ndim(s) else float(s) % self.length

    def gap(self, s_from, s_to):
        """Signed along-track gap s_to - s_from [m], wrapped into (-length/2, length/2]."""
        half = self.length / 2
        return half - np.mod(half - (np.asarray(s_to) - np.asarray(s_from)), self.length)

    def locate(self, s):
        """(segment index, local arc length t [m]) of s."""
        s = self.wrap_s(s)
        idx = np.searchsorted(self.starts, s, side="right") - 1
        return idx, s - self.starts[idx]

    # --- poses ------------------------------------------------------------------------------------------
    def pose(self, s, d=0.0):
        """World (x [m], y [m], tangent heading [rad]) at (s, d); arrays welcome."""
        if np.ndim(s) == 0 and np.ndim(d) == 0:
            i, t = self.locate(s)
            seg = self.segments[int(i)]
            x, y = seg.position(t, d)
            return float(x), float(y), float(seg.heading(t))
        s, d = np.broadcast_arrays(np.asarray(s, dtype=np.float64), np.asarray(d, dtype=np.float64))
        idx, t = self.locate(s)
        x, y, h = np.empty_like(s), np.empty_like(s), np.empty_like(s)
        for i in np.unique(idx):
            m = idx == i
            seg = self.segments[int(i)]
            x[m], y[m] = seg.position(t[m], d[m])
            h[m] = seg.heading(t[m])
        return x, y, h

    def heading(self, s):
        """Tangent heading [rad] at s."""
        return self.pose(s)[2]

    def curvature(self, s):
        """Signed curvature [1/m] at s (positive turning left)."""
        if isinstance(s, float) or np.ndim(s) == 0:
            return self.segments[bisect.bisect_right(self._starts_list, float(s) % self.length) - 1].curvature
        idx, _ = self.locate(s)
        return self._kappa[idx]

    def frenet(self, x, y, s_hint=None):
        """(s [m], d [m]) of world points: the projection onto the nearest part of the centreline.

        With s_hint (an array like x: a recent s of each point, e.g. a car's s one step ago), each point is
        first projected onto the segment of its hint only, which keeps per-step car tracking cheap; points
        that fall outside that segment are searched everywhere.
        """
        scalar = np.ndim(x) == 0 and np.ndim(y) == 0
        x, y = np.atleast_1d(np.asarray(x, dtype=np.float64)), np.atleast_1d(np.asarray(y, dtype=np.float64))
        if s_hint is not None:
            s_out, d_out = np.zeros_like(x), np.zeros_like(x)
            found = np.zeros(len(x), dtype=bool)
            seg_idx, _ = self.locate(np.atleast_1d(np.asarray(s_hint, dtype=np.float64)))
            for i in np.unique(seg_idx):
                sel = np.flatnonzero(seg_idx == i)
                seg = self.segments[int(i)]
                t, d = seg.local_coordinates(x[sel], y[sel])
                # a point near a joint may belong to the neighbour segment: those go to the full search
                ok = (t >= 0.0) & (t <= seg.length) & (np.abs(d) < 0.5 / max(abs(seg.curvature), 1e-9))
                s_out[sel[ok]], d_out[sel[ok]], found[sel[ok]] = self.starts[i] + t[ok], d[ok], True
            if not found.all():
                s_out[~found], d_out[~found] = self.frenet(x[~found], y[~found])
            s_out = self.wrap_s(s_out)
            return (float(s_out[0]), float(d_out[0])) if scalar else (s_out, d_out)
        best_s = np.zeros_like(x)
        best_d = np.full_like(x, np.inf)
        for seg, s0 in zip(self.segments, self.starts):
            t, d = seg.local_coordinates(x, y)
            inside = (t >= -1e-6) & (t <= seg.length + 1e-6)
            better = inside & (np.abs(d) < np.abs(best_d))
            best_s[better] = s0 + np.clip(t[better], 0.0, seg.length)
            best_d[better] = d[better]
        lost = ~np.isfinite(best_d)
        if lost.any():  # outside every segment's normal range (the seam's closure gap): nearest sample
            ss = np.arange(0.0, self.length, 0.5)
            px, py, ph = self.pose(ss)
            for i in np.flatnonzero(lost):
                k = int(np.argmin(np.hypot(px - x[i], py - y[i])))
                best_s[i] = ss[k]
                best_d[i] = -(x[i] - px[k]) * math.sin(ph[k]) + (y[i] - py[k]) * math.cos(ph[k])
        best_s = self.wrap_s(best_s)
        return (float(best_s[0]), float(best_d[0])) if scalar else (best_s, best_d)

    # --- cross-section ------------------------------------------------------------------------------------
    def lane_of(self, d):
        """Lane index (0 = leftmost) of a lateral offset d [m]; off-road counts in the outermost lane."""
        if np.ndim(d) == 0:  # the hot path: one car at a time
            return min(max(math.floor((self.markings[0] - float(d)) / self.lane_width), 0), self.lanes - 1)
        k = np.floor((self.markings[0] - np.asarray(d, dtype=np.float64)) / self.lane_width)
        return np.clip(k, 0, self.lanes - 1).astype(int)

    def on_road(self, d, margin: float = 0.0) -> bool:
        """True when |d| [m] is within the road's edges widened by `margin` [m]."""
        return abs(d) <= self.half_width + margin

    # --- straights ------------------------------------------------------------------------------------------
    def straight_ahead(self, s) -> float:
        """Metres of straight road ahead of s (0 on an arc); consecutive straights count as one."""
        i, t = self.locate(s)
        i = int(i)
        run = self._fast_straight[i]
        return 0.0 if run == 0.0 else float(run - t)

    def _straight_runs(self) -> list[float]:
        """For each segment: the length of straight from its start to the end of its run of straights."""
        n = len(self.segments)
        straight = [seg.kind == "straight" for seg in self.segments]
        runs = [0.0] * n
        if all(straight):
            return [math.inf] * n
        for i in range(n):
            if not straight[i]:
                continue
            total, j = 0.0, i
            while straight[j % n]:
                total += self.segments[j % n].length
                j += 1
            runs[i] = total
        return runs

    # --- closure ------------------------------------------------------------------------------------------
    def closure_error(self) -> tuple[float, float]:
        """Distance [m] and heading difference [rad] between the end of the last segment and s = 0."""
        x, y, h = self.segments[-1].end_pose()
        x0, y0, h0 = self.segments[0].x0, self.segments[0].y0, self.segments[0].heading0
        return math.hypot(x - x0, y - y0), abs(float(wrap_angle(h - h0)))

    def min_radius(self) -> float:
        radii = [seg.radius for seg in self.segments if isinstance(seg, Arc)]
        return min(radii) if radii else math.inf

    def sample(self, step: float = 2.0) -> np.ndarray:
        """Centreline s values every `step` metres or less, with every segment boundary included."""
        out = []
        for seg, s0 in zip(self.segments, self.starts):
            n = max(1, int(math.ceil(seg.length / step)))
            out.append(s0 + np.linspace(0.0, seg.length, n, endpoint=False))
        return np.concatenate(out)
