"""The host car: a kinematic bicycle integrated in track (Frenet) coordinates.

Driven by TORCS-style commands (core.worlds.highway.Action). Integrating in (s, d, heading relative to the
tangent) keeps the ground truth exact: no projection from world coordinates is needed each step.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from core.worlds.highway import STEER_LOCK_RAD, Action
from sim.bicycle import bicycle_move
from sim.track import Track


@dataclass(frozen=True)
class VehicleParams:
    wheelbase: float = 2.7           # [m]
    rear_to_cg: float = 1.35         # [m] rear axle to centre of gravity (the reference point)
    length: float = 4.6              # [m] body, for collisions
    width: float = 1.9               # [m]
    steer_lock: float = STEER_LOCK_RAD  # [rad] wheel angle at steer = 1
    steer_rate: float = 2.0          # [rad/s] how fast the wheels follow the command
    max_accel: float = 4.5           # [m/s^2] at standstill, falling linearly to 0 at top speed
    top_speed: float = 50.0          # [m/s]
    max_brake: float = 11.0          # [m/s^2] about 1.1 g, a TORCS car's: the Chen follow law brakes late
    drag: float = 4.0e-4             # [1/m] aerodynamic deceleration = drag * v^2
    rolling: float = 0.15            # [m/s^2]
    max_lateral_accel: float = 9.0   # [m/s^2] grip; beyond it the car runs wide (understeer)
    substep: float = 0.01            # [s] integration step


@dataclass
class VehicleState:
    s: float = 0.0          # [m]
    d: float = 0.0          # [m] positive left
    heading: float = 0.0    # [rad] yaw minus the track tangent, counter-clockwise positive
    speed: float = 0.0      # [m/s]
    wheel_angle: float = 0.0  # [rad] front wheel angle, positive left


def step_vehicle(state: VehicleState, action: Action, dt: float, track: Track,
                 p: VehicleParams = VehicleParams()) -> VehicleState:
    """Advance the host car by dt [s] under a constant command."""
    a = action.clipped()
    target = a.steer * p.steer_lock
    s, d, psi, v, delta = state.s, state.d, state.heading, state.speed, state.wheel_angle
    n = max(1, int(math.ceil(dt / p.substep - 1e-9)))
    h = dt / n
    for _ in range(n):
        delta += max(-p.steer_rate * h, min(p.steer_rate * h, target - delta))
        accel = a.accel * p.max_accel * max(0.0, 1.0 - v / p.top_speed)
        decel = a.brake * p.max_brake + p.drag * v * v + (p.rolling if v > 0 else 0.0)
        v = max(0.0, v + (accel - decel) * h)
        s, d, psi = bicycle_move(track, s, d, psi, v, delta, h, p.wheelbase, p.rear_to_cg, p.max_lateral_accel,
                                 grip_above=1.0)
    psi = (psi + math.pi) % (2 * math.pi) - math.pi
    return VehicleState(track.wrap_s(s), d, psi, v, delta)
