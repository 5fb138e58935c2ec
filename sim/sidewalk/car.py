"""The 1/10-scale car: MultiNet's steering and motor commands, a kinematic bicycle integrated in path (Frenet)
coordinates, as the highway's host car is (sim/highway/vehicle.py), so the truth needs no projection each step.

Commands, as on MultiNet's cars (Chowdhuri, Pankaj and Zipser, MultiNet, 2017): steer in [0, 1], 0.5 straight,
1 full right, 0 full left; motor in [0, 1], 0.5 stop, 1 full speed forward (about 9 m/s), 0 full reverse. The
motor is a speed command, as an RC car's electronic speed control behaves: the car's speed follows
(2 * motor - 1) * top speed with a first-order lag, its acceleration limited; reverse is capped lower.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from core.worlds.sidewalk import CAR_LENGTH, CAR_WIDTH, REAR_TO_CG, STEER_LOCK_RAD, TOP_SPEED, WHEELBASE
from sim.bicycle import bicycle_move
from sim.track.track import Track


@dataclass(frozen=True)
class CarParams:
    length: float = CAR_LENGTH      # [m] body, for collisions and border distances
    width: float = CAR_WIDTH        # [m]
    height: float = 0.16            # [m] body (drawn as the lead car)
    wheelbase: float = WHEELBASE    # [m]
    rear_to_cg: float = REAR_TO_CG  # [m] rear axle to the reference point (the body's centre)
    steer_lock: float = STEER_LOCK_RAD  # [rad] front-wheel angle at steer 0 (left) or 1 (right): 0.64 m radius
    steer_rate: float = 8.0         # [rad/s] servo speed (about 0.1 s lock to lock)
    top_speed: float = TOP_SPEED    # [m/s] at motor 1
    reverse_speed: float = 3.0      # [m/s] at most, backwards
    speed_lag: float = 0.25         # [s] time constant of the speed's response to the motor command
    max_accel: float = 5.0          # [m/s^2]
    max_brake: float = 8.0          # [m/s^2] slowing down (a speed command below the current speed)
    max_lateral_accel: float = 7.0  # [m/s^2] grip; beyond it the car runs wide
    substep: float = 1 / 90         # [s] integration step (3 per 30 Hz step)


CAR = CarParams()


@dataclass
class CarState:
    s: float = 0.0            # [m] along the path's centreline
    d: float = 0.0            # [m] from the centreline, positive left
    heading: float = 0.0      # [rad] yaw minus the path tangent, counter-clockwise
    speed: float = 0.0        # [m/s] negative in reverse
    wheel_angle: float = 0.0  # [rad] front wheels, positive left


def wheel_target(steer: float, p: CarParams = CAR) -> float:
    """Front-wheel angle [rad, positive left] a steering command asks for: steer 0.5 -> 0, 1 -> full right."""
    return (1.0 - 2.0 * min(1.0, max(0.0, steer))) * p.steer_lock


def speed_target(motor: float, p: CarParams = CAR) -> float:
    """Speed [m/s] a motor command asks for: 0.5 -> 0, 1 -> top speed, 0 -> reverse (capped)."""
    v = (2.0 * min(1.0, max(0.0, motor)) - 1.0) * p.top_speed
    return max(v, -p.reverse_speed)


def steer_command(wheel_angle: float, p: CarParams = CAR) -> float:
    """Inverse of wheel_target: the steering command for a wheel angle [rad, positive left], clipped to [0, 1]."""
    return min(1.0, max(0.0, 0.5 - wheel_angle / (2.0 * p.steer_lock)))


def motor_command(speed: float, p: CarParams = CAR) -> float:
    """Inverse of speed_target for forward speeds: the motor command for a speed [m/s], clipped to [0, 1]."""
    return min(1.0, max(0.0, 0.5 + speed / (2.0 * p.top_speed)))


def step_car(state: CarState, steer: float, motor: float, dt: float, track: Track, p: CarParams = CAR) -> CarState:
    """Advance the car by dt [s] under constant commands."""
    target, v_cmd = wheel_target(steer, p), speed_target(motor, p)
    s, d, psi, v, delta = state.s, state.d, state.heading, state.speed, state.wheel_angle
    n = max(1, int(math.ceil(dt / p.substep - 1e-9)))
    h = dt / n
    for _ in range(n):
        delta += max(-p.steer_rate * h, min(p.steer_rate * h, target - delta))
        accel = (v_cmd - v) / p.speed_lag
        slowing = (v_cmd - v) * v < 0 or v_cmd == 0.0
        limit = p.max_brake if slowing else p.max_accel
        v += max(-limit, min(limit, accel)) * h
        s, d, psi = bicycle_move(track, s, d, psi, v, delta, h, p.wheelbase, p.rear_to_cg, p.max_lateral_accel,
                                 grip_above=0.5)
    psi = (psi + math.pi) % (2 * math.pi) - math.pi
    return CarState(track.wrap_s(s), d, psi, v, delta)
