"""`RecentIds`: the highest ids, never more than twice its limit."""

from __future__ import annotations

import pytest

from fleet.mission.recent_ids import RecentIds


def test_it_remembers_what_was_added() -> None:
    ids = RecentIds(4)
    for mission in (3, 1, 2):
        ids.add(mission)
    assert 1 in ids and 2 in ids and 3 in ids and 4 not in ids
    assert sorted(ids) == [1, 2, 3]


def test_a_flood_of_ids_stays_bounded_and_keeps_the_newest() -> None:
    ids = RecentIds(1024)
    for mission in range(100_000):
        ids.add(mission)
        assert len(ids) <= 2048
    assert 99_999 in ids and 100_000 - 1024 in ids
    assert 0 not in ids


def test_a_limit_below_one_is_refused() -> None:
    with pytest.raises(ValueError, match="at least one"):
        RecentIds(0)
