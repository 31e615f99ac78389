"""A generated fleet (`fleet up --uavs N`): N UAVs on a ring, as a scenario TOML."""

from __future__ import annotations

import math

from fleet.geo.mercator import MercatorProjection

#: First Piccolo ID of a generated (--uavs N) fleet.
FIRST_GENERATED_ID = 101
#: Centre of a generated fleet: Camp Roberts, California, as in the shipped scenarios.
GENERATED_CENTRE = (35.7200, -120.7650)


def ring_scenario(count: int, name: str = "ring") -> str:
    """A scenario TOML of `count` UAVs (ids 101, 102, ...) on a ring, all circling it.

    The ring's radius grows with the count so neighbours start >= 1 km apart, each
    flies tangent to the ring (counter-clockwise), and altitudes are staggered by 20 m
    (cycling every 100 UAVs, which are then kilometres apart) so neighbours never share
    a level.
    """
    if count < 1:
        raise ValueError("a fleet needs at least one UAV")
    radius = max(1500.0, 1000.0 * count / (2 * math.pi))
    projection = MercatorProjection(*GENERATED_CENTRE)
    lines = [
        f'description = "{count} generated UAVs on a ring of radius {radius:.0f} m"',
        "",
    ]
    for i in range(count):
        bearing = 2 * math.pi * i / count
        east, north = radius * math.sin(bearing), radius * math.cos(bearing)
        lat, lon = projection.to_latlon(east, north)
        heading = (math.degrees(bearing) - 90.0) % 360.0
        lines += [
            "[[uav]]",
            f"id = {FIRST_GENERATED_ID + i}",
            f"lat = {lat:.7f}",
            f"lon = {lon:.7f}",
            f"alt = {600.0 + 20.0 * (i % 100):.1f}",
            f"heading = {heading:.1f}",
            "airspeed = 22.0",
            "",
        ]
    return "\n".join(lines)
