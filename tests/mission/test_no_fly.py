"""Tests of a mission's no-fly zones: their checks, their part in the digest, their
decoding from the bus and the payload link's refusal of them."""

from __future__ import annotations

import math

import msgspec
import pytest

from fleet.consensus.assignment import results_digest
from fleet.consensus.mission_round import MissionRound, targets_problem
from fleet.mission.messages import MissionTargets, NoFlyZone, Target, UavResult
from fleet.mission.no_fly import mission_zone_problem, zones_bytes
from fleet.payload.protocol import PlanningProtocolError, encode_message

# A square of about 1.1 km around (35.75, -120.75).
BOX = NoFlyZone(
    ring=((35.745, -120.756), (35.745, -120.744), (35.755, -120.744), (35.755, -120.756)),
    name="town",
)
OUTSIDE = Target(35.70, -120.80, 600.0)
INSIDE = Target(35.75, -120.75, 600.0)


def mission(*targets: Target, zones: tuple[NoFlyZone, ...] = (BOX,)) -> MissionTargets:
    return MissionTargets(mission=7, team=(74, 112), targets=targets, zones=zones)


def test_a_valid_zone_with_targets_outside_it_passes() -> None:
    assert mission_zone_problem((BOX,), (OUTSIDE,)) is None
    assert targets_problem(mission(OUTSIDE)) is None


def test_a_target_inside_a_zone_is_refused_by_name() -> None:
    problem = targets_problem(mission(OUTSIDE, INSIDE))
    assert problem == "target 1 is inside no-fly zone 0 (town): no route reaches it"


def test_a_target_on_a_zone_edge_is_inside() -> None:
    edge = Target(35.745, -120.75, 600.0)
    assert mission_zone_problem((BOX,), (edge,)) is not None


@pytest.mark.parametrize(
    ("ring", "why"),
    [
        (((35.7, -120.7), (35.8, -120.8)), "at least 3"),
        (((35.7, -120.7), (35.8, -120.6), (35.8, -120.7), (35.7, -120.6)), "cross"),
        ((), "no vertices"),
        (((89.5, 0.0), (89.6, 0.0), (89.6, 1.0)), "poles"),
    ],
)
def test_a_bad_zone_is_refused_on_receipt(ring: tuple[tuple[float, float], ...], why: str) -> None:
    problem = targets_problem(mission(OUTSIDE, zones=(NoFlyZone(ring=ring),)))
    assert problem is not None and why in problem and "no-fly zone 0" in problem


def test_zones_out_of_range_or_too_many_vertices_fail_to_decode_from_the_bus() -> None:
    good = msgspec.json.encode(mission(OUTSIDE))
    assert msgspec.json.decode(good, type=MissionTargets).zones == (BOX,)
    huge = msgspec.json.encode(mission(OUTSIDE)).replace(b"35.745,", b"135.745,", 1)
    with pytest.raises(msgspec.ValidationError):
        msgspec.json.decode(huge, type=MissionTargets)
    ring = tuple(
        (35.0 + 0.01 * math.cos(k / 20), -120.0 + 0.01 * math.sin(k / 20)) for k in range(66)
    )
    many = msgspec.json.encode(mission(OUTSIDE, zones=(NoFlyZone(ring=ring),)))
    with pytest.raises(msgspec.ValidationError):
        msgspec.json.decode(many, type=MissionTargets)


def test_a_mission_without_zones_decodes_from_older_json() -> None:
    old = b'{"mission":7,"team":[74],"targets":[{"lat":35.7,"lon":-120.8,"alt":600.0}]}'
    assert msgspec.json.decode(old, type=MissionTargets).zones == ()


def test_zones_change_the_digest_and_no_zones_keep_it() -> None:
    results: dict[int, list[float | None]] = {74: [10.0, None], 112: [20.0, 30.0]}
    assert results_digest(results, zones_bytes(())) == results_digest(results)
    with_box = results_digest(results, zones_bytes((BOX,)))
    assert with_box != results_digest(results)
    moved = NoFlyZone(ring=((35.745, -120.757), *BOX.ring[1:]), name="town")
    assert results_digest(results, zones_bytes((moved,))) != with_box


def test_a_round_with_zones_commits_their_digest() -> None:
    targets = mission(OUTSIDE, Target(35.8, -120.7, 600.0))
    mission_round = MissionRound(targets=targets, own_id=74, started=0.0)
    for uav, times in ((74, (10.0, None)), (112, (40.0, 20.0))):
        mission_round.add_result(UavResult(mission=7, uav=uav, times=times))
    report = mission_round.decide(alive={74, 112})
    used = {74: (10.0, None), 112: (40.0, 20.0)}
    assert report.digest == results_digest(used, zones_bytes((BOX,)))
    assert report.pairs == {74: 0, 112: 1}


def test_the_payload_link_refuses_a_mission_with_zones() -> None:
    with pytest.raises(PlanningProtocolError, match="no room for them"):
        encode_message(mission(OUTSIDE), 0xFFFE, 0xFFFF)
    assert encode_message(mission(OUTSIDE, zones=()), 0xFFFE, 0xFFFF)


def test_too_many_vertices_in_all_are_refused() -> None:
    def ring(k: int) -> tuple[tuple[float, float], ...]:
        return tuple(
            (10.0 * k + 0.01 * math.cos(i * math.tau / 60), 0.01 * math.sin(i * math.tau / 60))
            for i in range(60)
        )

    four = tuple(NoFlyZone(ring=ring(k)) for k in range(4))
    assert mission_zone_problem(four) is None  # 240 vertices
    problem = mission_zone_problem((*four, NoFlyZone(ring=ring(5))))
    assert problem == "no-fly zones: 300 vertices in all, more than the 256 a mission may have"
