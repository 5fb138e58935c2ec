"""Closed-loop metrics of the sidewalk world, fed with its truth records (one per 33 ms step).

Distance, mean speed, collisions (events: steps where a contact begins) and time in contact, time off the path,
obstacles met, the lead car's mean distance and its spread (follow), the mean distance to the nearer border while
one is beside the car (furtive), the time the expert corrected, the contacts begun while the expert held the wheel
(the correction rule acted too late if there are any), the take-overs and their seconds by the clause of the
correction rule that caused them (from `correction`, which names the rule that ran, or set by whoever ran it), and
percentage autonomy as Chowdhuri, Pankaj and Zipser define it (MultiNet, 2017): (1 - correction time / elapsed
time) * 100. The one place they are computed: the plugin's `metrics(world)` is this class, fed with observations.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from dataclasses import field as dc_field

import numpy as np

from controller.sidewalk.correction import CorrectionRule
from controller.sidewalk.experts import BORDER_CAP, GAP_CAP
from core.worlds.sidewalk import MODES, SIDEWALK

STAGES = ("render", "transfer", "perception", "control", "physics", "truth")
_I = {n: i for i, n in enumerate(SIDEWALK.truth_names)}


@dataclass
class SidewalkMetrics:
    dt: float                               # [s] one step
    steps: int = 0
    distance: float = 0.0                   # [m]
    collisions: int = 0
    collision_steps: int = 0
    off_path_steps: int = 0
    off_path_events: int = 0
    obstacles_met: int = 0
    correction_steps: int = 0
    corrections: int = 0                    # take-overs
    collisions_correcting: int = 0          # contacts begun while the expert held the wheel
    rule: str | None = None                 # the correction rule that ran (correctional operation)
    clauses: dict | None = None             # {clause: {"take_overs": n, "seconds": s}}
    wall_time: float = 0.0                  # [s]
    stage_time: dict = dc_field(default_factory=lambda: {s: 0.0 for s in STAGES})
    mode_steps: dict = dc_field(default_factory=lambda: {m: 0 for m in MODES})
    lead_gaps: list = dc_field(default_factory=list)
    border_gaps: list = dc_field(default_factory=list)
    # the correction rule of a correctional run at report time (None: none ran), for `rule` and `clauses`
    correction: Callable[[], CorrectionRule | None] | None = dc_field(default=None, repr=False)
    _prev: dict = dc_field(default_factory=lambda: {"collision": False, "off_path": False, "near": False,
                                                    "correcting": False})

    def observe(self, obs) -> None:
        """One step of the world's observation: its truth record."""
        self.update(obs.record)

    def update(self, record) -> None:
        r = np.asarray(record, dtype=np.float64)
        self.steps += 1
        self.distance += abs(r[_I["speed"]]) * self.dt
        flags = {"collision": bool(r[_I["collision"]]), "off_path": bool(r[_I["off_path"]]),
                 "near": bool(r[_I["obstacle_near"]]), "correcting": bool(r[_I["correcting"]])}
        prev = self._prev
        began = flags["collision"] and not prev["collision"]
        self.collisions += int(began)
        self.collisions_correcting += int(began and flags["correcting"])
        self.collision_steps += int(flags["collision"])
        self.off_path_events += int(flags["off_path"] and not prev["off_path"])
        self.off_path_steps += int(flags["off_path"])
        self.obstacles_met += int(flags["near"] and not prev["near"])
        self.corrections += int(flags["correcting"] and not prev["correcting"])
        self.correction_steps += int(flags["correcting"])
        self._prev = flags
        mode = MODES[int(r[_I["behaviour"]])]
        self.mode_steps[mode] += 1
        if mode == "follow" and r[_I["lead_gap"]] < GAP_CAP:
            self.lead_gaps.append(float(r[_I["lead_gap"]]))
        nearer = min(r[_I["border_left"]], r[_I["border_right"]])
        if mode == "furtive" and nearer < BORDER_CAP:
            self.border_gaps.append(float(nearer))

    def add_time(self, stage: str, seconds: float) -> None:
        self.stage_time[stage] = self.stage_time.get(stage, 0.0) + seconds

    def report(self) -> dict:
        rule = self.correction() if self.correction is not None else None
        if rule is not None:
            self.rule, self.clauses = rule.rule, rule.tally.report(self.dt)
        t = self.steps * self.dt
        per_step = {k: (v / self.steps * 1e3 if self.steps else 0.0) for k, v in self.stage_time.items()}
        lead = np.array(self.lead_gaps)
        border = np.array(self.border_gaps)
        return {
            "simulated_time_s": round(t, 3),
            "distance_m": round(self.distance, 1),
            "mean_speed_mps": round(self.distance / t, 3) if t else 0.0,
            "collisions": self.collisions,
            "collision_time_s": round(self.collision_steps * self.dt, 3),
            "off_path_time_s": round(self.off_path_steps * self.dt, 3),
            "off_path_events": self.off_path_events,
            "obstacles_met": self.obstacles_met,
            "mean_lead_gap_m": round(float(lead.mean()), 3) if lead.size else None,
            "lead_gap_std_m": round(float(lead.std()), 3) if lead.size else None,
            "mean_border_distance_m": round(float(border.mean()), 3) if border.size else None,
            "share_beside_a_border": round(border.size / self.mode_steps["furtive"], 4)
            if self.mode_steps["furtive"] else None,
            "correction_time_s": round(self.correction_steps * self.dt, 3),
            "corrections": self.corrections,
            "collisions_while_correcting": self.collisions_correcting,
            "rule": self.rule,
            "take_overs_by_clause": self.clauses,
            "autonomy_percent": round((1.0 - self.correction_steps / self.steps) * 100.0, 2) if self.steps else 100.0,
            "mode_share": {m: round(n / self.steps, 4) if self.steps else 0.0 for m, n in self.mode_steps.items()},
            "loop_rate_hz": round(self.steps / self.wall_time, 1) if self.wall_time else 0.0,
            "realtime_factor": round(t / self.wall_time, 2) if self.wall_time else 0.0,
            "stage_ms_per_step": {k: round(v, 3) for k, v in per_step.items()},
        }

    def table(self) -> str:
        r = self.report()
        stages = r.pop("stage_ms_per_step")
        shares = r.pop("mode_share")
        clauses = r.pop("take_overs_by_clause") or {}
        rows = ["| metric | value |", "|---|---|"] + [f"| {k} | {'-' if v is None else v} |" for k, v in r.items()]
        rows.append("| mode share | " + ", ".join(f"{m} {s:.0%}" for m, s in shares.items() if s) + " |")
        rows += [f"| take-overs: {c} | {v['take_overs']} ({v['seconds']:.1f} s) |" for c, v in clauses.items()]
        rows += [f"| ms/step {k} | {v} |" for k, v in stages.items()]
        return "\n".join(rows)
