"""The director of a scripted scenario (sim/highway/scripted.py): before every step it checks each event's trigger
against the host and the actors as the world last saw them, and carries out what fires through SUMO's commands
(sim/highway/sumo_traffic.py: set_speed, change_lane, release).

- A time trigger fires at the first step whose start time is at or after its time.
- A gap trigger fires at the first step where the actor's gap to the host (centre to centre along the road,
  positive ahead) has reached its value from the side it started on: a slower car ahead fires at "gap 12" as the
  host closes to 12 m, a faster car from behind at "gap 12" once it is 12 m ahead. A jump of more than a quarter
  lap is the gap's wrap half a lap away, not a crossing.
- A speed change (brake, stop, slow) starts from the actor's speed when it fires and sets a new speed every step,
  `rate * dt` nearer its target, until it is there; the next speed event of that actor replaces it.
- A lane change moves the actor one lane (towards the host's lane, or left or right) over SUMO's lane-change
  duration (2 s); it does nothing when the actor is in the host's lane already or no lane is there, and says so.
- resume hands the actor to SUMO's car-following and lane changing, wanting the given speed (default: its own).

Everything is computed from the world's state and the scenario, so the same scenario and driver give the same
commands step for step. `fired` lists what was carried out: time, actor, event and what it did.
"""
from __future__ import annotations

import math

import numpy as np

from sim.highway.scripted import Event, ScriptedScenario
from sim.highway.traffic import CarStates

EPS = 1e-9


class Director:
    def __init__(self, scenario: ScriptedScenario, dt: float):
        self.scenario, self.dt = scenario, dt
        self.track = scenario.track
        self.fired: list[dict] = []
        self._pending = list(range(len(scenario.events)))
        self._last_gap: dict[int, float] = {}                       # gap-triggered event -> its actor's last gap
        self._side: dict[int, float] = {}                           # ... -> the side of its value it started on
        self._ramps: dict[int, tuple[float, float, float]] = {}     # actor -> (speed set, target, rate)

    def before_step(self, t: float, ego_s: float, ego_d: float, cars: CarStates, traffic) -> None:
        """Fire what is due at time `t` [s], then set this step's speeds."""
        n = len(self.scenario.actors)
        gaps = np.asarray(self.track.gap(ego_s, cars.s[:n]), dtype=np.float64)
        for k in list(self._pending):
            event = self.scenario.events[k]
            if self._due(k, event, t, float(gaps[event.actor])):
                self._pending.remove(k)
                self._carry_out(k, event, t, ego_d, cars, traffic)
        for i, (speed, target, rate) in list(self._ramps.items()):
            step = rate * self.dt
            speed = target if abs(target - speed) <= step + EPS else speed + math.copysign(step, target - speed)
            traffic.set_speed(i, speed)
            if speed == target:
                del self._ramps[i]   # SUMO holds the last speed set
            else:
                self._ramps[i] = (speed, target, rate)

    def _due(self, k: int, event: Event, t: float, gap: float) -> bool:
        if event.time is not None:
            return t >= event.time - EPS
        assert event.gap is not None
        last = self._last_gap.get(k)
        self._last_gap[k] = gap
        side = gap - event.gap
        if k not in self._side:
            self._side[k] = side
        if last is not None and abs(gap - last) > self.track.length / 4:   # the wrap half a lap away
            self._side[k] = side
            return False
        return side == 0 or (side > 0) != (self._side[k] > 0)

    def _carry_out(self, k: int, event: Event, t: float, ego_d: float, cars: CarStates, traffic) -> None:
        i, tr = event.actor, self.track
        note = ""
        if event.do == "change_lane":
            lane, host = int(tr.lane_of(float(cars.d[i]))), int(tr.lane_of(ego_d))
            step = {"left": -1, "right": 1}.get(event.towards, int(np.sign(host - lane)))
            target = lane + step
            if step == 0:
                note = "already in the host's lane: nothing done"
            elif not 0 <= target < tr.lanes:
                note = f"no lane to its {'left' if step < 0 else 'right'}: nothing done"
            else:
                traffic.change_lane(i, target)
                note = f"from lane {lane} to lane {target}"
        elif event.do == "resume":
            self._ramps.pop(i, None)
            speed = event.speed if event.speed is not None else float(cars.speed[i])
            traffic.release(i, speed)
            note = f"SUMO drives it, wanting {speed:.1f} m/s"
        else:
            assert event.speed is not None and event.rate is not None
            self._ramps[i] = (float(cars.speed[i]), event.speed, event.rate)
            note = f"from {float(cars.speed[i]):.1f} to {event.speed:g} m/s at {event.rate:g} m/s^2"
        self.fired.append({"t": round(t, 3), "event": k, "actor": self.scenario.actors[i].name, "do": event.do,
                           "note": note})
