"""A mission's no-fly zones: checked the same way on the ground and on every UAV.

A mission is refused (on the ground before anything is sent, on a UAV on receipt) when
a zone is not a usable polygon (fleet.geo.zones.validate_ring: closed, not
self-intersecting, 3 to 64 vertices), when its zones have more than
`MAX_MISSION_ZONE_VERTICES` vertices together, or when a target lies inside a zone or
on its edge: no route could reach it without entering. Each zone is checked on the local plane
of its own first vertex, so the check does not depend on where the aircraft are.

The zones are part of the mission's digest (`zones_bytes`, hashed with the results by
fleet.consensus.assignment.results_digest): UAVs that planned around different zones
never report the same digest.
"""

from __future__ import annotations

from collections.abc import Sequence

import msgspec

from fleet.geo.mercator import MercatorProjection
from fleet.geo.zones import Ring, ZoneError, point_in_ring, ring_to_local, validate_ring
from fleet.mission.messages import NoFlyZone, Target

__all__ = [
    "MAX_MISSION_ZONE_VERTICES",
    "local_zones",
    "mission_zone_problem",
    "zone_label",
    "zones_bytes",
]

#: Vertices of all a mission's zones together, at most: every UAV computes the
#: sightlines between them at each plan (about 60 ms at this many: docs/benchmarks.md),
#: so a hostile mission cannot stall the planners.
MAX_MISSION_ZONE_VERTICES = 256


def zone_label(index: int, zone: NoFlyZone) -> str:
    return f"no-fly zone {index}" + (f" ({zone.name})" if zone.name else "")


def _ring(index: int, zone: NoFlyZone) -> tuple[MercatorProjection, Ring]:
    """The zone on its own local plane (ZoneError if it is not a usable polygon)."""
    label = zone_label(index, zone)
    if not zone.ring:
        raise ZoneError(f"{label}: no vertices")
    try:
        projection = MercatorProjection(*zone.ring[0])
        return projection, validate_ring(ring_to_local(projection, zone.ring), label)
    except ZoneError:
        raise
    except ValueError as error:  # a vertex the projection refuses (a pole, NaN)
        raise ZoneError(f"{label}: {error}") from None


def mission_zone_problem(zones: Sequence[NoFlyZone], targets: Sequence[Target] = ()) -> str | None:
    """Why these zones (with these targets) cannot be flown; None if they can."""
    total = sum(len(zone.ring) for zone in zones)
    if total > MAX_MISSION_ZONE_VERTICES:
        return (
            f"no-fly zones: {total} vertices in all, more than the "
            f"{MAX_MISSION_ZONE_VERTICES} a mission may have"
        )
    for index, zone in enumerate(zones):
        try:
            projection, ring = _ring(index, zone)
        except ZoneError as error:
            return str(error)
        for t, target in enumerate(targets):
            try:
                inside = point_in_ring(projection.to_xy(target.lat, target.lon), ring)
            except ValueError:
                continue  # the targets' own check says what is wrong with it
            if inside:
                return f"target {t} is inside {zone_label(index, zone)}: no route reaches it"
    return None


def local_zones(projection: MercatorProjection, zones: Sequence[NoFlyZone]) -> tuple[Ring, ...]:
    """Every zone's ring on `projection`'s plane (zones checked beforehand)."""
    return tuple(ring_to_local(projection, zone.ring) for zone in zones)


def zones_bytes(zones: Sequence[NoFlyZone]) -> bytes:
    """The zones as the bytes the mission's digest hashes; empty for no zones (the
    digest of a mission without zones is the one it always was)."""
    return msgspec.json.encode(tuple(zones)) if zones else b""
