"""The kinematic bicycle both worlds' cars move by, integrated in a track's (Frenet) coordinates: one substep.

Integrating in (s, d, heading relative to the tangent) keeps the ground truth exact: no projection from world
coordinates is needed each step.
"""
from __future__ import annotations

import math

from sim.track import Track


def bicycle_move(track: Track, s: float, d: float, psi: float, v: float, delta: float, h: float, wheelbase: float,
                 rear_to_cg: float, max_lateral_accel: float, grip_above: float) -> tuple[float, float, float]:
    """One substep of h [s] of the kinematic bicycle in the track's frame: (s, d, heading) after it, at speed v
    [m/s] (negative: reversing) and front wheel angle delta. The path curvature at the CG is capped by the grip
    available at this speed once |v| > grip_above; both the highway car and the sidewalk car move by it."""
    beta = math.atan(rear_to_cg * math.tan(delta) / wheelbase)
    kappa_car = math.cos(beta) * math.tan(delta) / wheelbase
    if abs(v) > grip_above:   # grip: beyond it the car runs wide
        cap = max_lateral_accel / (v * v)
        kappa_car = max(-cap, min(cap, kappa_car))
    kappa = track.curvature(s)
    s_dot = v * math.cos(psi + beta) / (1.0 - kappa * d)
    d += v * math.sin(psi + beta) * h
    psi += (v * kappa_car - kappa * s_dot) * h
    return s + s_dot * h, d, psi
