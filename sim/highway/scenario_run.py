"""A scripted scenario inside a world (sim/highway/world.py): where the host starts, the traffic with the scenario's
cars, the director that carries out its events (sim/highway/director.py) and the judge of its criteria
(sim/highway/criteria.py). A world's reset builds a new one, so every reset replays the scenario from its start."""
from __future__ import annotations

from sim.highway.config import WorldConfig
from sim.highway.criteria import Judge
from sim.highway.director import Director
from sim.highway.scripted import ScriptedScenario
from sim.highway.sumo_traffic import ActorStart, SumoTraffic
from sim.highway.traffic import CarStates, ScriptedTraffic
from sim.highway.vehicle import VehicleState


class ScenarioRun:
    def __init__(self, scenario: ScriptedScenario, config: WorldConfig):
        self.scenario, self.config = scenario, config
        self.director = Director(scenario, config.dt)
        self.judge = Judge(scenario.criteria, scenario.track, scenario.host.lane, config.vehicle.length)

    def host_start(self) -> VehicleState:
        h, tr = self.scenario.host, self.scenario.track
        return VehicleState(s=h.s, d=float(tr.lane_centres[h.lane]) + h.offset, heading=h.heading, speed=h.speed)

    def traffic(self, ego_pose, ego_speed: float) -> SumoTraffic | ScriptedTraffic:
        """SUMO with the scenario's cars and its AI traffic (nothing at all to drive: no SUMO)."""
        sc, c = self.scenario, self.config
        if not sc.actors and not sc.traffic:
            return ScriptedTraffic(sc.track, [], [], [], seed=sc.seed)
        actors = tuple(ActorStart(s, int(sc.track.lane_of(d)), v, m, a.blind)
                       for (s, d, v, m), a in zip(sc.placements(), sc.actors))
        return SumoTraffic(sc.track, sc.traffic, seed=sc.seed, dt=c.dt, ego=ego_pose, ego_speed=ego_speed,
                           transport=c.sumo, actors=actors)

    def before_step(self, t: float, ego: VehicleState, cars: CarStates, traffic) -> None:
        if self.scenario.actors:
            self.director.before_step(t, ego.s, ego.d, cars, traffic)

    def observe(self, obs, cars: CarStates) -> None:
        self.judge.observe(obs, cars)

    def report(self) -> dict:
        """The scenario's name, the events carried out so far and the verdict so far."""
        return {"scenario": self.scenario.name, "events": list(self.director.fired), **self.judge.verdict()}
