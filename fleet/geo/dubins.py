"""Analytic Dubins-path time from an aircraft's state to a point.

This is the documented fallback of the approach-time model: when the LP budget runs out
(or the solver fails) the planner still owes the fleet an approach time for every
target, and the shortest path of a constant-speed, bank-limited aircraft to a point is
cheap to compute in closed form.

The target is a point, not a pose: the final heading is free. For that problem the
shortest path is a turn at the minimum radius followed by a straight line (CS), or, for
points inside a turn circle, two turns in opposite directions (CC) (Bui, Souères,
Boissonnat and Laumond, 1994). All four families (LS, RS, LR, RL) are evaluated where
they exist and the shortest is returned; every candidate is a flyable path, so taking
the minimum never under-estimates the optimum.

In a steady wind (`dubins_time_in_wind`) the aircraft flies the same paths in the air
mass, where the target is not still: seen from the air it drifts at minus the wind. The
time T is then the first root of L(target - wind T) / V = T, with L the still-air path
length above: the moving virtual target of McGee, Spry and Hedrick (AIAA GNC 2005),
found by a 1-D root search. The turns flown are circles in the air and trochoids over the ground.

Frames: x east, y north, metres; headings are mathematical angles (counter-clockwise
from east), so a left turn increases the angle.
"""

from __future__ import annotations

import math
from typing import NamedTuple

from fleet.geo.angles import TWO_PI, wrap_two_pi
from fleet.geo.wind import CALM_AIR, Wind

__all__ = ["dubins_path_length", "dubins_time_in_wind", "dubins_time_to_point"]

_ARC_EPS = 1e-9


def _ccw(angle: float) -> float:
    """Angle wrapped into [0, 2*pi): the arc swept counter-clockwise.

    An arc within rounding of a full turn is a zero arc computed from two nearly equal
    angles (a target dead ahead), not a loop.
    """
    wrapped = wrap_two_pi(angle)
    return 0.0 if wrapped > TWO_PI - _ARC_EPS else wrapped


class _Turn(NamedTuple):
    """The first turn of a path: on the circle `centre` of `radius`, from the point seen
    at `start_angle` from the centre, turning `direction` (+1 left, -1 right)."""

    centre: tuple[float, float]
    start_angle: float
    direction: float
    radius: float


def _turn_then_straight(turn: _Turn, target: tuple[float, float]) -> float:
    """Length of the CS path that starts with `turn`.

    Returns inf if the target lies inside the circle (no tangent exists).
    """
    centre, start_angle, direction, radius = turn
    dx = target[0] - centre[0]
    dy = target[1] - centre[1]
    dist = math.hypot(dx, dy)
    # A target on the circle (the start point itself, say) may land a rounding error
    # inside it.
    if dist < radius * (1.0 - 1e-9):
        return math.inf
    straight = math.sqrt(max(dist * dist - radius * radius, 0.0))
    # The tangent point Q sees the target along the direction of travel, so the angle of
    # Q (seen from the centre) lags the target's angle by atan2(straight, r) in the
    # direction of the turn.
    exit_angle = math.atan2(dy, dx) - direction * math.atan2(straight, radius)
    arc = _ccw(direction * (exit_angle - start_angle))
    return radius * arc + straight


def _turn_then_turn(turn: _Turn, target: tuple[float, float]) -> float:
    """Length of the shortest CC path that starts with `turn`.

    The second circle touches the first one on the far side of the switching point, so
    its centre lies at 2r from the first centre, and it must pass through the target:
    its centre is at r from the target. Returns inf when those circles do not meet.
    """
    (cx, cy), start_angle, direction, radius = turn
    dx = target[0] - cx
    dy = target[1] - cy
    d = math.hypot(dx, dy)
    if d < radius or d > 3.0 * radius or d == 0.0:
        return math.inf
    # Intersection of circle(centre, 2r) and circle(target, r), by the law of cosines.
    cos_half = ((2.0 * radius) ** 2 + d * d - radius * radius) / (4.0 * radius * d)
    half = math.acos(max(-1.0, min(1.0, cos_half)))
    base = math.atan2(dy, dx)
    best = math.inf
    for switch_angle in (base + half, base - half):
        first_arc = _ccw(direction * (switch_angle - start_angle))
        second_cx = cx + 2.0 * radius * math.cos(switch_angle)
        second_cy = cy + 2.0 * radius * math.sin(switch_angle)
        # On the second circle the switching point is seen at switch_angle + pi and the
        # aircraft now turns the other way.
        target_angle = math.atan2(target[1] - second_cy, target[0] - second_cx)
        second_arc = _ccw(-direction * (target_angle - (switch_angle + math.pi)))
        best = min(best, radius * (first_arc + second_arc))
    return best


def dubins_path_length(
    position: tuple[float, float],
    heading: float,
    target: tuple[float, float],
    radius: float,
) -> float:
    """Length in metres of the shortest bounded-curvature path to a point.

    `heading` in radians counter-clockwise from east; `radius` is the minimum turn
    radius (0 gives the straight-line distance).
    """
    dx = target[0] - position[0]
    dy = target[1] - position[1]
    if radius <= 0.0:
        return math.hypot(dx, dy)
    if math.hypot(dx, dy) <= 1e-6 * radius:
        # Already there. Near the start the tangent construction takes the square root of
        # a difference of nearly equal squares, and its rounding could turn a zero arc
        # into a full loop.
        return math.hypot(dx, dy)
    if not math.isfinite(radius):
        # The aircraft cannot turn: only points dead ahead are reachable.
        along = dx * math.cos(heading) + dy * math.sin(heading)
        cross = -dx * math.sin(heading) + dy * math.cos(heading)
        return along if along >= 0.0 and abs(cross) <= 1e-9 * max(1.0, along) else math.inf
    best = math.inf
    for direction in (1.0, -1.0):
        # The turn centre is on the left (+1) or right (-1) of the heading.
        centre = (
            position[0] - direction * radius * math.sin(heading),
            position[1] + direction * radius * math.cos(heading),
        )
        start_angle = math.atan2(position[1] - centre[1], position[0] - centre[0])
        turn = _Turn(centre, start_angle, direction, radius)
        best = min(best, _turn_then_straight(turn, target), _turn_then_turn(turn, target))
    return best


def dubins_time_to_point(
    position: tuple[float, float],
    velocity: tuple[float, float],
    target: tuple[float, float],
    turn_radius: float,
) -> float:
    """Seconds to fly the shortest Dubins path from (position, velocity) to `target`.

    The speed is |velocity| and stays constant; the heading is the velocity's direction.
    A stationary aircraft has no heading and cannot fly, so it gets inf unless it is
    already on the target.
    """
    speed = math.hypot(velocity[0], velocity[1])
    if speed <= 0.0:
        on_target = position[0] == target[0] and position[1] == target[1]
        return 0.0 if on_target else math.inf
    heading = math.atan2(velocity[1], velocity[0])
    return dubins_path_length(position, heading, target, turn_radius) / speed


#: The root search stops within this many seconds of the arrival time.
_ROOT_TOLERANCE_S = 1e-6
#: Bound on the root search's steps: the safe step shrinks the gap at least by the factor
#: 2 |w| / (V + |w|) per step, so at |w| = 0.7 V this is far more than 1e-6 s needs.
_ROOT_STEPS = 400


def dubins_time_in_wind(
    position: tuple[float, float],
    air_velocity: tuple[float, float],
    target: tuple[float, float],
    turn_radius: float,
    wind: Wind = CALM_AIR,
) -> float:
    """Seconds to fly the shortest Dubins path in the air mass to a point on the ground.

    `air_velocity` is the aircraft's velocity through the air (its heading and airspeed
    V, held constant); `wind` the air mass's velocity over the ground. The aircraft flies
    a still-air Dubins path in the air to where the target will be, seen from the air,
    when it arrives (module docstring). inf if the wind is as fast as the aircraft.
    """
    speed = math.hypot(air_velocity[0], air_velocity[1])
    if not wind:
        return dubins_time_to_point(position, air_velocity, target, turn_radius)
    if speed <= wind.speed:
        on_target = position[0] == target[0] and position[1] == target[1]
        return 0.0 if on_target else math.inf
    heading = math.atan2(air_velocity[1], air_velocity[0])

    def excess(t: float) -> float:
        """Path time to where the target is seen at `t`, minus `t`: > 0 before arrival."""
        drifted = (target[0] - wind.east * t, target[1] - wind.north * t)
        return dubins_path_length(position, heading, drifted, turn_radius) / speed - t

    # The path length changes at most as fast as the virtual target moves (|w|) except
    # where it jumps up (the target entering a turn circle), so `excess` falls at most at
    # 1 + |w| / V a second: a step of excess / that can never pass the first root.
    # A path can always be lengthened, so the arrival is the first t with excess <= 0.
    rate = 1.0 + wind.speed / speed
    t = 0.0
    gap = excess(t)
    for _ in range(_ROOT_STEPS):
        if gap <= 0.0:
            break
        if gap <= _ROOT_TOLERANCE_S:
            return t
        before = t
        t += gap / rate
        gap = excess(t)
    else:
        return t + gap
    # Jumped down across a discontinuity (the target leaving a turn circle): the first
    # feasible time lies between the last step and this one.
    for _ in range(60):
        if t - before <= _ROOT_TOLERANCE_S:
            break
        middle = 0.5 * (before + t)
        if excess(middle) > 0.0:
            before = middle
        else:
            t = middle
    return t
