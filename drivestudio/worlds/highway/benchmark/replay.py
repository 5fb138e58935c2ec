"""From a crash clip to a scripted scenario (docs/scenarios.md): the seconds before a collision, written as a file that
`benchmark --scenarios`, `drive --scenario` and the studio replay, so that a failure becomes a test.

The scenario starts REPLAY_BEFORE seconds before the collision, with the host where it was (its lane, its offset in
it, its heading and speed) and every car that came within REPLAY_RANGE of it in those seconds as an actor where it
was then. Each actor is blind (it follows its script whatever is ahead: what it did already includes how it reacted)
and its script is what the clip's truth shows it doing: its speed every SPEED_STEP seconds, as ramps from one to
the next, and a lane change wherever it left its lane centre for another lane.

The driver starts afresh: whatever it remembered at that moment (the Chen controller's lane timers, a network's
filters) is not in the file. REPLAY_BEFORE is longer than rule 1's 6 s, so that a lane change the driver began in
the clip can be begun again in the replay.
"""
from __future__ import annotations

import numpy as np

from sim.highway.footprints import MODEL_NAMES
from sim.highway.scripted import MAX_HEADING, MAX_OFFSET_SHARE, MAX_RATE, VERSION

REPLAY_BEFORE = 8.0      # [s] of the clip's truth the scenario starts before the collision
REPLAY_AFTER = 2.0       # [s] the scenario goes on after the collision's time
REPLAY_RANGE = 60.0      # [m] a car that comes this near the host (centre to centre) in those seconds is an actor
SPEED_STEP = 0.5         # [s] an actor's speed is scripted as a ramp from one such instant to the next
SPEED_TOLERANCE = 0.05   # [m/s] a change of speed smaller than this over SPEED_STEP is not scripted
LANE_CENTRE = 0.05       # [m] farther than this from its lane's centre, a car has begun to change lanes


def replay_scenario(entries: list, track, route, t_event: float, name: str, about: str) -> dict | None:
    """The scenario (a JSON object) of `entries` (the clip's steps up to the collision, each with its `obs` and
    `cars`), on `route`'s track, lanes and seed; None with fewer than two steps."""
    steps = [e for e in entries if e.cars is not None]
    if len(steps) < 2:
        return None
    rows = [_rows_by_car(e.cars) for e in steps]
    cars = sorted(set.intersection(*(set(r) for r in rows)))   # SUMO inserts some cars late: those there throughout
    t0 = float(steps[0].obs.t)
    host = _host(steps[0].obs.truth, track)
    lane = host["lane"]

    def column(field: str) -> np.ndarray:   # (steps, cars)
        return np.array([[getattr(e.cars, field)[r[c]] for c in cars] for e, r in zip(steps, rows)]).reshape(
            len(steps), len(cars))
    s, d, v = column("s"), column("d"), column("speed")
    ego_s = np.array([float(e.obs.truth.ego[3]) for e in steps])
    gaps = np.array([track.gap(a, b) for a, b in zip(ego_s, s)]).reshape(len(steps), len(cars))
    t = np.array([float(e.obs.t) for e in steps]) - t0
    models = column("models")[0]
    actors, events = [], []
    for i in np.flatnonzero(np.abs(gaps).min(axis=0) <= REPLAY_RANGE):
        actor = f"car{cars[i]}"
        car_lane = int(track.lane_of(float(d[0, i])))
        actors.append({"name": actor, "lane_offset": lane - car_lane, "gap": round(float(gaps[0, i]), 3),
                       "speed": round(float(v[0, i]), 4), "model": MODEL_NAMES[int(models[i])], "blind": True})
        events += _lane_changes(actor, t, d[:, i], track) + _speeds(actor, t, v[:, i])
    events.sort(key=lambda e: e["when"]["time"])
    return {"version": VERSION, "name": name, "description": about,
            "route": {"track": route.track_ref or route.track, "lanes": track.lanes, "traffic": 0, "seed": route.seed,
                      "seconds": round(t_event - t0 + REPLAY_AFTER, 1)},
            "host": host, "actors": actors, "events": events, "pass": {"no_collision": True}}


def _host(truth, track) -> dict:
    """The host's start: where it was (its lane, its offset in it), its heading and speed."""
    d = float(truth.ego[4])
    lane = int(track.lane_of(d))
    half = MAX_OFFSET_SHARE * track.lane_width
    return {"s": round(float(truth.ego[3]), 3), "lane": lane, "speed": round(float(truth.speed), 4),
            "offset": round(float(np.clip(d - track.lane_centres[lane], -half, half)), 4),
            "heading": round(float(np.clip(-truth.indicators[0], -MAX_HEADING, MAX_HEADING)), 5)}


def _rows_by_car(cars) -> dict[int, int]:
    """{car id: its row} of one step's cars (rows in order when they carry no ids)."""
    ids = cars.ids if cars.ids is not None else np.arange(len(cars))
    return {int(c): k for k, c in enumerate(ids)}


def _lane_changes(actor: str, t: np.ndarray, d: np.ndarray, track) -> list[dict]:
    """A change_lane wherever the car's centre moved into another lane, told at the step before it left its lane's
    centre (SUMO moves it from the next step on)."""
    lanes = np.asarray(track.lane_of(d))
    out = []
    for k in np.flatnonzero(lanes[1:] != lanes[:-1]) + 1:
        origin = int(lanes[k - 1])
        start = k - 1
        while start > 0 and abs(d[start] - track.lane_centres[origin]) > LANE_CENTRE:
            start -= 1
        out.append({"actor": actor, "when": {"time": round(float(t[start]), 3)}, "do": "change_lane",
                    "towards": "left" if lanes[k] < origin else "right"})
    return out


def _speeds(actor: str, t: np.ndarray, v: np.ndarray) -> list[dict]:
    """Ramps from the car's speed at every SPEED_STEP instant to its speed at the next one."""
    step = max(1, int(round(SPEED_STEP / float(t[1] - t[0]))))
    out, held = [], float(v[0])
    for k in range(0, len(v) - 1, step):
        nxt = float(v[min(k + step, len(v) - 1)])
        if abs(nxt - held) > SPEED_TOLERANCE:
            rate = min(MAX_RATE, abs(nxt - held) / SPEED_STEP)
            out.append({"actor": actor, "when": {"time": round(float(t[k]), 3)}, "do": "slow",
                        "speed": round(nxt, 4), "rate": round(max(rate, 0.01), 4)})
            held = nxt
    return out
