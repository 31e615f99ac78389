"""A reference for the approach-time model: pure pursuit flown step by step."""

from __future__ import annotations

import math

from fleet.geo.aircraft import AircraftLimits
from fleet.geo.angles import wrap_pi

Point = tuple[float, float]


def fly_pure_pursuit(
    position: Point,
    velocity: Point,
    target: Point,
    limits: AircraftLimits,
    dt: float = 0.02,
    max_time_s: float = 3000.0,
) -> float | None:
    """Seconds a constant-airspeed, bank-limited aircraft takes to reach `target`.

    The heading turns toward the target at the bank-limit rate (g tan(bank) / V) until
    it points at it, then holds; the airspeed is |velocity| clamped to the limits. The
    arrival is interpolated inside the last step. None if the target is not reached
    within `max_time_s` (e.g. inside the turn circle, where pure pursuit orbits).
    """
    speed = limits.clamp_airspeed(math.hypot(velocity[0], velocity[1]))
    heading = math.atan2(velocity[1], velocity[0])
    rate = limits.max_accel / speed
    x, y = position
    t = 0.0
    while t < max_time_s:
        dx = target[0] - x
        dy = target[1] - y
        dist = math.hypot(dx, dy)
        if dist <= speed * dt:
            return t + dist / speed
        error = wrap_pi(math.atan2(dy, dx) - heading)
        turn = max(-rate * dt, min(rate * dt, error))
        mid = heading + 0.5 * turn  # midpoint heading: second-order accurate arcs
        heading += turn
        x += speed * dt * math.cos(mid)
        y += speed * dt * math.sin(mid)
        t += dt
    return None
