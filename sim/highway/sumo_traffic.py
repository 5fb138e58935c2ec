"""AI traffic driven by SUMO.

SUMO runs in lock-step with the world at the world's step. The AI cars use SUMO's
own car-following (Krauss) and lane-change (LC2013) models with varied desired speeds and driver styles, so
they overtake each other and the host car. The host car is a SUMO vehicle too, moved to its true pose every
step, so AI cars brake behind it and change lanes around it. Poses come back with the conventions of
docs/affordances.md: SUMO's position is the front bumper and its angle is a compass heading; SUMO's lane 0
is the rightmost.

A scripted scenario's cars (actors, sim/highway/scripted.py) are SUMO vehicles too, placed first, at exactly the
given places (no insertion check holds them back), and driven by commands: a speed set every step, a lane change
carried out whatever is beside (sim/highway/director.py says when), until one is handed back to SUMO's own models.

The first SumoTraffic of a process runs SUMO inside it (libsumo, the fastest); any other open at the same time
runs its own `sumo` process over TraCI (sim/highway/sumo_connection.py). The same seed gives the same traffic
either way, so any number of worlds can run in one process.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from sim.highway.car_models import PAINTS, car_models
from sim.highway.config import MAX_CARS
from sim.highway.errors import TrafficError
from sim.highway.sumo_connection import TRANSPORTS, SumoConnection
from sim.highway.sumo_network import SPEED_LIMIT, SumoNetwork, network_for
from sim.highway.traffic import CarStates, assign_looks
from sim.track import Track

MIN_SPACING = 20.0        # [m] of lane per car: denser traffic cannot be inserted
EGO_CLEARANCE = 30.0      # [m] no AI car starts closer than this to the host car, along the loop
START_SPACING = 60.0      # [m] between cars of one lane at the start
LAPS_PER_ROUTE = 4        # routes are renewed before a car reaches their end, so cars circulate forever
RENEW_EVERY = 50          # steps between route renewals
EGO_ID = "ego"
EGO_SIZE = (4.6, 1.9)     # [m] length, width (sim.highway.vehicle.VehicleParams)
ACTOR_CLEARANCE = 20.0    # [m] no AI car starts closer than this to an actor of its lane
# SUMO's speed modes (bit 0 safe speed, 1 acceleration limit, 2 deceleration limit, 3-4 junctions): an actor keeps
# its distance to the car ahead but changes speed as fast as its script says; a blind one follows its script
# whatever is ahead; a released one drives by SUMO's own car-following (its default, 31)
ACTOR_SPEED_MODE, BLIND_SPEED_MODE, OWN_SPEED_MODE = 0b11001, 0, 31
# lane-change modes: a scripted actor changes lanes only when told, whatever is beside it (bits 8-9 zero); a
# released one by SUMO's own lane-change model (its default, 1621)
SCRIPTED_LANE_CHANGE_MODE, OWN_LANE_CHANGE_MODE = 0, 0b011001010101
HOLD_LANE = 3600.0        # [s] a commanded lane change holds the actor in its new lane this long (the scenario's end)

# (name, accel [m/s^2], decel [m/s^2], tau [s], imperfection sigma, lcSpeedGain, lcKeepRight)
DRIVER_STYLES = (
    ("calm", 2.0, 4.0, 1.4, 0.3, 0.6, 1.5),
    ("normal", 2.6, 4.5, 1.1, 0.4, 1.0, 1.0),
    ("sporty", 3.5, 6.0, 0.8, 0.2, 2.5, 0.5),
)


def car_count_problem(track: Track, n_cars) -> str | None:
    """Why `n_cars` AI cars cannot drive on `track` (None: they can), checked before SUMO starts."""
    if isinstance(n_cars, bool) or not isinstance(n_cars, (int, np.integer)) or not 0 <= n_cars <= MAX_CARS:
        return f"the number of AI cars must be an integer from 0 to {MAX_CARS}, got {n_cars!r}"
    capacity = int(track.lanes * track.length / MIN_SPACING)
    if n_cars > capacity:
        return (f"{n_cars} cars do not fit on track '{track.name}' with {track.lanes} lane(s) "
                f"({track.length:.0f} m): at most {capacity}")
    return None


@dataclass(frozen=True)
class ActorStart:
    """Where a scenario's actor starts: its centre's s [m], lane (0 = leftmost), speed [m/s] and car model."""

    s: float
    lane: int
    speed: float
    model: int = 0
    blind: bool = False   # follows its script whatever is ahead


class SumoTraffic:
    _started = False
    _conn: SumoConnection | None = None

    def __init__(self, track: Track, n_cars: int, seed: int = 0, dt: float = 0.1, ego: np.ndarray | None = None,
                 ego_speed: float = 0.0, transport: str = "auto", actors: tuple[ActorStart, ...] = ()):
        problem = car_count_problem(track, n_cars)
        if problem:
            raise TrafficError(problem)
        if transport not in TRANSPORTS:
            raise TrafficError(f"unknown SUMO transport {transport!r} (choose from {', '.join(TRANSPORTS)})")
        self.track, self.n_cars, self.seed, self.dt = track, int(n_cars), int(seed), float(dt)
        self.net: SumoNetwork = network_for(track)
        self._transport = transport
        self.actors = tuple(actors)
        # the actors come first: car i < len(actors) of states() is actor i
        self._ids = [f"actor{i}" for i in range(len(actors))] + [f"ai{i}" for i in range(self.n_cars)]
        models, paints = assign_looks(self.n_cars, seed)
        actor_paints = np.random.default_rng([int(seed), 0xAC7]).integers(0, len(PAINTS), len(actors))
        self.models = np.concatenate([np.array([a.model for a in actors], dtype=models.dtype), models])
        self.paints = np.concatenate([actor_paints.astype(paints.dtype), paints])
        dims = np.array([(m.length, m.width) for m in car_models()])
        self.length, self.width = dims[self.models, 0], dims[self.models, 1]
        self._steps = 0
        self._started = False
        self._last_s: np.ndarray | None = None  # per AI car, for cheap projection next step
        self._start(ego if ego is not None else np.array([*track.pose(0.0, 0.0), 0.0, 0.0]), ego_speed)

    # --- set-up ----------------------------------------------------------------------------------------------
    def _start(self, ego: np.ndarray, ego_speed: float) -> None:
        args = ["sumo", "-n", str(self.net.path), "--step-length", f"{self.dt}", "--seed", str(self.seed),
                "--no-step-log", "true", "--no-warnings", "true", "--duration-log.disable", "true",
                "--time-to-teleport", "-1", "--collision.action", "warn", "--collision.mingap-factor", "0",
                "--lanechange.duration", "2.0", "--default.speeddev", "0"]
        if self.actors:   # a scenario places its cars where it says, however close (it checked they do not overlap)
            args += ["--insertion-checks", "none"]
        try:
            self._conn = SumoConnection(args, self._transport)
        except TrafficError:
            raise
        except Exception as e:  # libsumo and traci raise their own TraCIException / FatalTraCIError
            raise TrafficError(f"SUMO failed to start on track '{self.track.name}': {e}") from None
        self._ls = self._conn.api
        self._started = True
        try:
            self._populate(ego, ego_speed)
        except TrafficError:
            self.close()
            raise
        except Exception as e:
            self.close()
            raise TrafficError(f"SUMO could not place the cars on track '{self.track.name}': {e}") from None

    def _loop_from(self, edge: int) -> list[str]:
        e = list(self.net.edges)
        return (e[edge:] + e[:edge]) * LAPS_PER_ROUTE

    def _edge_at(self, s: float) -> tuple[int, float]:
        """(edge index, distance along the edge [m]) of centreline position s; approximate off the centreline."""
        i = int(np.searchsorted(self.net.starts, s, side="right") - 1)
        return i, s - self.net.starts[i]

    def _populate(self, ego: np.ndarray, ego_speed: float) -> None:
        ls, tr = self._ls, self.track
        for i in range(len(self.net.edges)):
            ls.route.add(f"loop{i}", self._loop_from(i))
        models = car_models()
        for m, model in enumerate(models):
            for name, accel, decel, tau, sigma, _, _ in DRIVER_STYLES:
                t = f"m{m}{name}"
                ls.vehicletype.copy("DEFAULT_VEHTYPE", t)
                ls.vehicletype.setLength(t, model.length)
                ls.vehicletype.setWidth(t, model.width)
                ls.vehicletype.setMinGap(t, 2.0)
                ls.vehicletype.setAccel(t, accel)
                ls.vehicletype.setDecel(t, decel)
                ls.vehicletype.setTau(t, tau)
                ls.vehicletype.setImperfection(t, sigma)
                ls.vehicletype.setMaxSpeed(t, 50.0)
        ls.vehicletype.copy("DEFAULT_VEHTYPE", "egotype")
        ls.vehicletype.setLength("egotype", EGO_SIZE[0])
        ls.vehicletype.setWidth("egotype", EGO_SIZE[1])
        ls.vehicletype.setMaxSpeed("egotype", 60.0)

        rng = np.random.default_rng([self.seed, 0x5A0])
        ego_s = float(ego[3])
        # the host car goes in first, onto an empty road
        edge, pos = self._edge_at((ego_s + EGO_SIZE[0] / 2) % tr.length)
        ls.vehicle.add(EGO_ID, f"loop{edge}", typeID="egotype", departLane=str(tr.lanes - 1 - tr.lane_of(ego[4])),
                       departPos=f"{pos:.2f}", departSpeed=f"{max(0.0, ego_speed):.2f}")
        ls.vehicle.setSpeedMode(EGO_ID, 0)        # we move it; SUMO must not second-guess
        ls.vehicle.setLaneChangeMode(EGO_ID, 0)
        self._add_actors()
        slots = self._start_slots(rng, ego_s)
        first = len(self.actors)
        for i, vid in enumerate(self._ids[first:], start=first):
            s, lane = slots[i - first]
            style = int(rng.integers(0, len(DRIVER_STYLES)))
            # a fifth of the cars are slow; the rest spread up to the limit, so overtaking happens
            factor = rng.uniform(0.45, 0.6) if rng.uniform() < 0.2 else rng.uniform(0.6, 1.0)
            edge, pos = self._edge_at((s + self.length[i] / 2) % tr.length)  # SUMO places the front bumper
            ls.vehicle.add(vid, f"loop{edge}", typeID=f"m{self.models[i]}{DRIVER_STYLES[style][0]}",
                           departLane=str(tr.lanes - 1 - lane), departPos=f"{pos:.2f}",
                           departSpeed="max")  # the fastest that is safe behind whoever is ahead
            ls.vehicle.setSpeedFactor(vid, float(factor))
            ls.vehicle.setParameter(vid, "laneChangeModel.lcSpeedGain", str(DRIVER_STYLES[style][5]))
            ls.vehicle.setParameter(vid, "laneChangeModel.lcKeepRight", str(DRIVER_STYLES[style][6]))
        ls.simulationStep()
        present = ls.vehicle.getIDList()
        if EGO_ID not in present:
            raise TrafficError("SUMO could not insert the host car at its start position")
        missing = [vid for vid in self._ids[:len(self.actors)] if vid not in present]
        if missing:
            raise TrafficError(f"SUMO could not place the scenario's car {missing[0]}")
        # lane position -> s: each edge is all straight or all arc, so one ratio per lane converts exactly
        ends = list(self.net.starts[1:]) + [tr.length]
        self._lane_scale = np.array([[ls.lane.getLength(f"{e}_{j}") / (b - a) for j in range(tr.lanes)]
                                     for e, a, b in zip(self.net.edges, self.net.starts, ends)])

    def _add_actors(self) -> None:
        """The scenario's cars, at their places and speeds, each a vehicle type of its model that does not dawdle
        (SUMO's imperfection 0), so that what it does is what its script says."""
        ls, tr = self._ls, self.track
        for i, a in enumerate(self.actors):
            t = f"actor-m{a.model}"
            if t not in ls.vehicletype.getIDList():
                ls.vehicletype.copy(f"m{a.model}normal", t)
                ls.vehicletype.setImperfection(t, 0.0)
            vid = self._ids[i]
            edge, pos = self._edge_at((a.s + self.length[i] / 2) % tr.length)
            ls.vehicle.add(vid, f"loop{edge}", typeID=t, departLane=str(tr.lanes - 1 - a.lane), departPos=f"{pos:.2f}",
                           departSpeed=f"{a.speed:.4f}")
            ls.vehicle.setLaneChangeMode(vid, SCRIPTED_LANE_CHANGE_MODE)
            ls.vehicle.setSpeedMode(vid, BLIND_SPEED_MODE if a.blind else ACTOR_SPEED_MODE)
            ls.vehicle.setSpeed(vid, a.speed)

    def _start_slots(self, rng: np.random.Generator, ego_s: float) -> list[tuple[float, int]]:
        """Start positions (s [m], lane): a grid around the host car, as at a TORCS race start, half ahead and
        half behind, consecutive cars in turning lanes so that cars of one lane start about START_SPACING
        apart (or spread over the whole loop when there are many), none within EGO_CLEARANCE of the host."""
        tr, n = self.track, self.n_cars
        window = min(tr.length - 2 * EGO_CLEARANCE, n * START_SPACING / tr.lanes)
        slots = []
        for j in range(n):
            offset = ((j + 0.5 + 0.3 * rng.uniform(-1, 1)) / n - 0.5) * window
            offset += EGO_CLEARANCE if offset >= 0 else -EGO_CLEARANCE
            slots.append(self._clear_of_actors(float((ego_s + offset) % tr.length), j % tr.lanes))
        return slots

    def _clear_of_actors(self, s: float, lane: int) -> tuple[float, int]:
        """A start slot moved on along its lane, in steps of ACTOR_CLEARANCE, until no actor of that lane is within
        ACTOR_CLEARANCE of it (unchanged without actors)."""
        tr = self.track
        for _ in range(int(tr.length // ACTOR_CLEARANCE)):
            if all(a.lane != lane or abs(float(tr.gap(a.s, s))) >= ACTOR_CLEARANCE for a in self.actors):
                break
            s = (s + ACTOR_CLEARANCE) % tr.length
        return s, lane

    # --- per step ------------------------------------------------------------------------------------------------
    def _move_ego(self, ego: np.ndarray, speed: float) -> None:
        """Put SUMO's host car where ours is. moveTo is 500x cheaper than moveToXY's map matching; SUMO then
        advances it by speed * dt in the step, so it is placed that much behind."""
        tr = self.track
        edge, along = self._edge_at((float(ego[3]) + EGO_SIZE[0] / 2) % tr.length)  # SUMO tracks the front
        lane = tr.lanes - 1 - tr.lane_of(float(ego[4]))
        length = self._lane_scale[edge, lane] * (
            (self.net.starts[edge + 1] if edge + 1 < len(self.net.starts) else tr.length) - self.net.starts[edge])
        pos = min(max(along * self._lane_scale[edge, lane] - speed * self.dt, 0.1), length - 0.1)
        self._ls.vehicle.moveTo(EGO_ID, f"{self.net.edges[edge]}_{lane}", pos)
        self._ls.vehicle.setSpeed(EGO_ID, max(0.0, float(speed)))

    def _renew_routes(self) -> None:
        ls, k = self._ls, len(self.net.edges)
        for vid in ls.vehicle.getIDList():
            if ls.vehicle.getRouteIndex(vid) >= k:
                edge = self.net.edges.index(ls.vehicle.getRoadID(vid))
                ls.vehicle.setRoute(vid, self._loop_from(edge))

    def step(self, dt: float, ego: np.ndarray, ego_speed: float = 0.0) -> None:
        """Advance SUMO by one step with the host car at its true pose [x, y, yaw, s, d] and speed [m/s]."""
        if abs(dt - self.dt) > 1e-9:
            raise TrafficError(f"SUMO steps {self.dt} s at a time, the world asked for {dt} s")
        self._move_ego(ego, ego_speed)
        self._ls.simulationStep()
        self._steps += 1
        if self._steps % RENEW_EVERY == 0:
            self._renew_routes()

    def collisions(self) -> int:
        """Collisions SUMO reported in the last step (AI-AI and AI-host)."""
        return int(self._ls.simulation.getCollidingVehiclesNumber())

    def states(self) -> CarStates:
        ls, tr = self._ls, self.track
        present = set(ls.vehicle.getIDList())
        present_idx = [i for i, vid in enumerate(self._ids) if vid in present]
        if not present_idx:
            return CarStates.empty()
        idx = np.array(present_idx)
        assert self._conn is not None, "SUMO traffic is closed"
        front, angle, speed = self._conn.car_readings([self._ids[i] for i in idx])
        yaw = np.radians(90.0 - angle)
        half = self.length[idx] / 2
        x, y = front[:, 0] - half * np.cos(yaw), front[:, 1] - half * np.sin(yaw)
        hint = None if self._last_s is None else self._last_s[idx]
        s, d = tr.frenet(x, y, s_hint=hint)
        if self._last_s is None:
            self._last_s = np.zeros(len(self._ids))
        self._last_s[idx] = s
        return CarStates(x, y, yaw, np.atleast_1d(s), np.atleast_1d(d), self.length[idx], self.width[idx],
                         self.models[idx], self.paints[idx], speed, idx)

    def lane_index(self, i: int) -> int:
        """Our lane (0 = leftmost) that SUMO has car i (of states()' order, actors first) on."""
        return self.track.lanes - 1 - int(self._ls.vehicle.getLaneIndex(self._ids[i]))

    # --- commands to a scenario's actors (sim/highway/director.py) -----------------------------------------------
    def set_speed(self, i: int, speed: float) -> None:
        """Actor i drives at `speed` [m/s] from the next step on (slower only to keep its distance, unless blind);
        an actor SUMO drove is taken back under the script."""
        v = self._ls.vehicle
        v.setSpeedMode(self._ids[i], BLIND_SPEED_MODE if self.actors[i].blind else ACTOR_SPEED_MODE)
        v.setLaneChangeMode(self._ids[i], SCRIPTED_LANE_CHANGE_MODE)
        v.setSpeed(self._ids[i], max(0.0, float(speed)))

    def change_lane(self, i: int, lane: int) -> None:
        """Actor i moves into our lane `lane` (0 = leftmost) over SUMO's lane-change duration, whatever is beside."""
        self._ls.vehicle.changeLane(self._ids[i], self.track.lanes - 1 - int(lane), HOLD_LANE)

    def release(self, i: int, speed: float) -> None:
        """Actor i drives by SUMO's own car-following and lane changing from now on, wanting `speed` [m/s]."""
        v, vid = self._ls.vehicle, self._ids[i]
        v.setSpeedFactor(vid, max(0.01, float(speed)) / SPEED_LIMIT)
        v.setSpeed(vid, -1.0)
        v.setSpeedMode(vid, OWN_SPEED_MODE)
        v.setLaneChangeMode(vid, OWN_LANE_CHANGE_MODE)

    @property
    def transport(self) -> str:
        """How this traffic talks to SUMO: "libsumo" (in this process) or "traci" (its own sumo process)."""
        return self._conn.transport if self._conn is not None else "closed"

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None
        self._started = False
