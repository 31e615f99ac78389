"""Angle wrapping, the one place every package takes it from.

Radians for headings and course errors (`wrap_two_pi`, `wrap_pi`), degrees for
longitudes (`wrap_degrees`). All three are half-open so that each angle has exactly one
representative.
"""

from __future__ import annotations

import math

__all__ = ["TWO_PI", "wrap_degrees", "wrap_pi", "wrap_two_pi"]

TWO_PI = 2.0 * math.pi


def wrap_two_pi(angle: float) -> float:
    """`angle` (radians) wrapped to [0, 2 pi)."""
    wrapped = angle % TWO_PI
    # `%` can return 2 pi itself for tiny negative inputs.
    return 0.0 if wrapped >= TWO_PI else wrapped


def wrap_pi(angle: float) -> float:
    """`angle` (radians) wrapped to [-pi, pi): a signed turn, left positive in math frames."""
    return (angle + math.pi) % TWO_PI - math.pi


def wrap_degrees(angle: float) -> float:
    """`angle` (degrees) wrapped to [-180, 180)."""
    return (angle + 180.0) % 360.0 - 180.0
