"""Piccolo IDs to MAVLink system ids: identity for 1-254, `--sysid` for the rest, and
every collision refused."""

from __future__ import annotations

import argparse

import pytest

from ground.mavlink.sysids import SysIdError, SysIdMap, sysid_pair


def test_ids_1_to_254_are_their_own_system_id() -> None:
    ids = SysIdMap()
    assert ids.sysid_of(1) == 1
    assert ids.sysid_of(254) == 254
    assert ids.piccolo_of(74) == 74


def test_ids_above_254_need_a_mapping_and_are_told_how() -> None:
    ids = SysIdMap()
    assert ids.sysid_of(255) is None
    assert ids.sysid_of(300) is None
    assert "--sysid 300=SYS" in ids.why_hidden(300)
    mapped = SysIdMap([(300, 30)])
    assert mapped.sysid_of(300) == 30
    assert mapped.piccolo_of(30) == 300


def test_a_uav_whose_own_id_was_given_away_is_hidden_not_mixed() -> None:
    ids = SysIdMap([(300, 30)])
    assert ids.sysid_of(30) is None
    assert "given to UAV 300" in ids.why_hidden(30)
    # ... unless it is mapped elsewhere itself.
    both = SysIdMap([(300, 30), (30, 31)])
    assert both.sysid_of(30) == 31
    assert both.piccolo_of(31) == 30
    assert both.piccolo_of(30) == 300


def test_a_remapped_uav_frees_nothing_it_does_not_own() -> None:
    ids = SysIdMap([(74, 5)])
    assert ids.sysid_of(74) == 5
    assert ids.piccolo_of(74) is None  # UAV 74 is system 5 now
    assert ids.piccolo_of(5) == 74


def test_two_uavs_on_one_system_id_are_refused() -> None:
    with pytest.raises(SysIdError, match="system id 30 given to both UAV 300 and UAV 400"):
        SysIdMap([(300, 30), (400, 30)])


def test_one_uav_mapped_twice_is_refused() -> None:
    with pytest.raises(SysIdError, match="UAV 300 mapped twice"):
        SysIdMap([(300, 30), (300, 31)])


def test_the_same_pair_twice_is_harmless() -> None:
    assert SysIdMap([(300, 30), (300, 30)]).sysid_of(300) == 30


@pytest.mark.parametrize("text", ["300", "300=0", "300=255", "300=x", "0=5", "70000=5"])
def test_bad_sysid_arguments_are_usage_errors(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError):
        sysid_pair(text)


def test_sysid_argument() -> None:
    assert sysid_pair("300=12") == (300, 12)
