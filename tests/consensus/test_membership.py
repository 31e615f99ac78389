"""Membership counts (fleet.consensus.membership): out and back again, merged in any
order to the same view; the two sides of a partition converge."""

from __future__ import annotations

import itertools

from hypothesis import given
from hypothesis import strategies as st

from fleet.consensus.membership import Membership, membership_digest, own_asked, report_counts

TEAM = frozenset({101, 102, 103, 104})


def test_out_and_back_again() -> None:
    view = Membership(TEAM)
    assert view.leave([102]) == {102} and view.out() == {102} and view.epoch == 1
    assert view.leave([102]) == set()  # already out: counted once
    assert view.come_back([102]) == {102} and view.out() == frozenset() and view.epoch == 2
    assert view.leave([102]) == {102} and view.left[102] == 2 and view.epoch == 3
    assert view.leave([999]) == set()  # not of the team


def test_two_sides_of_a_partition_converge_once_they_hear_each_other() -> None:
    a, b = Membership(TEAM), Membership(TEAM)
    a.leave([103, 104])  # the side {101, 102} lost sight of {103, 104}
    b.leave([101, 102])  # and the other way round
    # Healed: each merges the other's counts, and sees the other side come back.
    a.merge(b.left, b.back)
    b.merge(a.left, a.back)
    a.come_back(TEAM)
    b.come_back(TEAM)
    assert a.out() == b.out() == frozenset()
    assert (a.left, a.back) == (b.left, b.back) and a.epoch == b.epoch == 8
    assert membership_digest("d", a.left, a.back) == membership_digest("d", b.left, b.back)


def test_a_uav_outside_the_plan_is_counted_in_as_out_once_and_back_once() -> None:
    view = Membership(TEAM)
    assert view.join([103]) == {103} and view.out() == frozenset() and view.epoch == 2
    assert view.join([103]) == set()  # counted once
    assert view.join([999]) == set()  # not of the team
    view.leave([104])
    assert view.join([104]) == set()  # counted already (out: it comes back, not joins)
    # Two UAVs that count it in set the same counts, in either order with a merge.
    other = Membership(TEAM)
    other.join([103])
    other.merge(view.left, view.back)
    view.merge(other.left, other.back)
    assert (view.left, view.back) == (other.left, other.back)


def test_a_report_without_counts_counts_its_released_uavs_out_once() -> None:
    assert report_counts((102,), {}, {}) == ({102: 1}, {})
    assert report_counts((102,), {102: 3}, {101: 1}) == ({102: 3}, {101: 1})


EVENTS = st.lists(
    st.tuples(st.sampled_from(["leave", "back"]), st.sampled_from(sorted(TEAM))), max_size=12
)


@given(st.lists(EVENTS, min_size=2, max_size=4))
def test_merging_in_any_order_gives_the_same_counts(histories: list[list[tuple[str, int]]]) -> None:
    views = []
    for history in histories:
        view = Membership(TEAM)
        for what, uav in history:
            (view.leave if what == "leave" else view.come_back)([uav])
        views.append(view)
    results = set()
    for order in itertools.permutations(views):
        merged = Membership(TEAM)
        for view in order:
            merged.merge(view.left, view.back)
        assert all(merged.covers(v.left, v.back) for v in views)
        results.add((tuple(sorted(merged.left.items())), tuple(sorted(merged.back.items()))))
    assert len(results) == 1


def test_re_plans_asked_in_changed_air_are_counted_in_the_epoch_and_merged_in_any_order() -> None:
    a, b = Membership(TEAM), Membership(TEAM)
    assert a.ask(101) and a.asked == {101: 1} and a.epoch == 1 and a.out() == frozenset()
    assert not a.ask(999)  # not of the team
    b.leave([104])
    b.ask(102)
    b.ask(102)
    a.merge(b.left, b.back, b.asked)
    b.merge(a.left, a.back, a.asked)
    assert (a.left, a.back, a.asked) == (b.left, b.back, b.asked)
    assert a.asked == {101: 1, 102: 2} and a.left == {104: 1}
    assert a.epoch == b.epoch == 4
    assert a.covers(b.left, b.back, b.asked) and not a.covers({}, {}, {101: 2})
    digest = membership_digest("d", a.left, a.back, a.asked)
    assert digest == membership_digest("d", b.left, b.back, b.asked)
    # Asked counts name another plan; none asked leaves the digest of before.
    assert digest != membership_digest("d", a.left, a.back)
    assert membership_digest("d", a.left, a.back, {}) == membership_digest("d", a.left, a.back)


def test_an_ask_is_counted_from_its_askers_own_report_not_from_a_teammates() -> None:
    # 102 says 101 asked three times and itself once: only its own ask is believed.
    assert own_asked(102, {101: 3, 102: 1}) == {102: 1}
    assert own_asked(102, {101: 3}) == {}  # nothing of its own: nothing taken
    view = Membership(TEAM)
    assert not view.merge({}, {}, own_asked(102, {101: 3}))
    assert view.asked == {} and view.epoch == 0  # no epoch in 101's name
    assert view.merge({}, {}, own_asked(101, {101: 1, 103: 5}))
    assert view.asked == {101: 1} and view.epoch == 1


ASK_REPORTS = st.lists(
    st.tuples(
        st.sampled_from(sorted(TEAM)),  # the report's author
        st.dictionaries(st.sampled_from(sorted(TEAM)), st.integers(1, 4), max_size=4),
    ),
    min_size=1,
    max_size=6,
)


@given(ASK_REPORTS)
def test_asks_believed_of_their_authors_merge_to_the_same_counts_in_any_order(
    reports: list[tuple[int, dict[int, int]]],
) -> None:
    results = set()
    for order in itertools.islice(itertools.permutations(reports), 24):
        view = Membership(TEAM)
        for author, asked in order:
            view.merge({}, {}, own_asked(author, asked))
        results.add(tuple(sorted(view.asked.items())))
        # Each count is the largest its own UAV reported of itself, whoever else spoke.
        for uav, count in view.asked.items():
            assert count == max(a.get(uav, 0) for author, a in reports if author == uav)
    assert len(results) == 1
