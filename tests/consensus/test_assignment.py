"""Tests for the deterministic greedy assignment (thesis 4.4.3) and the results digest."""

from __future__ import annotations

import hashlib
import math
import random
import struct
from collections.abc import Mapping, Sequence

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from fleet.consensus.assignment import (
    Assignment,
    greedy_assign,
    results_digest,
    row_bytes,
    row_order,
)

Results = dict[int, list[float | None]]

# Small integer-valued times make ties common, which is where a weak order would show.
_tied_time = st.integers(min_value=0, max_value=4).map(float)
_any_time = st.floats(min_value=0.0, max_value=1e4, allow_nan=False)
_answer = st.one_of(
    st.none(), _tied_time, _any_time, st.sampled_from([math.nan, math.inf, -math.inf])
)


@st.composite
def results_strategy(
    draw: st.DrawFn,
    max_uavs: int = 6,
    max_targets: int = 6,
    times: st.SearchStrategy[float | None] = _answer,
) -> tuple[Results, int]:
    n_targets = draw(st.integers(min_value=0, max_value=max_targets))
    uavs = draw(
        st.lists(st.integers(min_value=0, max_value=0xFFFD), unique=True, max_size=max_uavs)
    )
    results: Results = {
        uav: draw(st.lists(times, min_size=n_targets, max_size=n_targets)) for uav in uavs
    }
    return results, n_targets


def reference_greedy(results: Results, n_targets: int) -> dict[int, int]:
    """The thesis's rule written as naively as possible: pick the least triple, drop
    everything sharing its UAV or target, repeat."""
    remaining = [
        (time, uav, target)
        for uav, row in results.items()
        for target, time in enumerate(row)
        if time is not None and math.isfinite(time)
    ]
    pairs: dict[int, int] = {}
    while remaining:
        _, uav, target = min(remaining)
        pairs[uav] = target
        remaining = [t for t in remaining if t[1] != uav and t[2] != target]
    return pairs


def _check_consistent(a: Assignment, results: Results, n_targets: int) -> None:
    assert len(set(a.pairs.values())) == len(a.pairs), "a target went to two UAVs"
    assert set(a.pairs) <= set(results)
    assert set(a.pairs) | set(a.idle_uavs) == set(results)
    assert not set(a.pairs) & set(a.idle_uavs)
    assert set(a.pairs.values()) | set(a.unassigned_targets) == set(range(n_targets))
    assert not set(a.pairs.values()) & set(a.unassigned_targets)
    assert list(a.unassigned_targets) == sorted(a.unassigned_targets)
    assert list(a.idle_uavs) == sorted(a.idle_uavs)
    for uav, target in a.pairs.items():
        time = results[uav][target]
        assert time is not None and math.isfinite(time), "an unanswered entry was assigned"


@given(results_strategy())
def test_one_target_per_uav_and_one_uav_per_target(case: tuple[Results, int]) -> None:
    results, n_targets = case
    _check_consistent(greedy_assign(results, n_targets), results, n_targets)


@given(results_strategy(times=st.one_of(_tied_time, _any_time)))
def test_everything_reachable_gives_min_pairs(case: tuple[Results, int]) -> None:
    results, n_targets = case
    a = greedy_assign(results, n_targets)
    assert len(a.pairs) == min(len(results), n_targets)


@given(results_strategy(), st.randoms(use_true_random=False))
def test_invariant_to_mapping_order(case: tuple[Results, int], rnd: random.Random) -> None:
    results, n_targets = case
    items = list(results.items())
    rnd.shuffle(items)
    shuffled = dict(items)
    a, b = greedy_assign(results, n_targets), greedy_assign(shuffled, n_targets)
    assert a == b
    assert list(a.pairs) == list(b.pairs)  # even the dict's iteration order
    assert results_digest(results) == results_digest(shuffled)


@settings(max_examples=300)
@given(results_strategy())
def test_equals_naive_reference(case: tuple[Results, int]) -> None:
    results, n_targets = case
    assert greedy_assign(results, n_targets).pairs == reference_greedy(results, n_targets)


@given(results_strategy(max_uavs=20, max_targets=50, times=_any_time))
@settings(max_examples=25)
def test_equals_naive_reference_large(case: tuple[Results, int]) -> None:
    results, n_targets = case
    assert greedy_assign(results, n_targets).pairs == reference_greedy(results, n_targets)


def test_tie_on_time_goes_to_lowest_piccolo_id() -> None:
    # Insertion order puts the higher ID first so that order cannot be what decides.
    a = greedy_assign({112: [5.0], 74: [5.0]}, 1)
    assert a.pairs == {74: 0}
    assert a.idle_uavs == (112,)
    assert a.unassigned_targets == ()


def test_tie_within_one_uav_goes_to_lowest_target_index() -> None:
    a = greedy_assign({74: [7.0, 3.0, 3.0, 3.0]}, 4)
    assert a.pairs == {74: 1}
    assert a.unassigned_targets == (0, 2, 3)


def test_tie_across_uavs_and_targets() -> None:
    # All four entries tie: (3, 10, 0) is least, which leaves (3, 20, 1).
    a = greedy_assign({20: [3.0, 3.0], 10: [3.0, 3.0]}, 2)
    assert a.pairs == {10: 0, 20: 1}


def test_negative_zero_ties_with_zero() -> None:
    a = greedy_assign({9: [0.0], 3: [-0.0]}, 1)
    assert a.pairs == {3: 0}


def test_shortest_time_wins_over_lower_id() -> None:
    a = greedy_assign({1: [10.0], 2: [9.999]}, 1)
    assert a.pairs == {2: 0}


def test_thesis_two_uavs_three_targets() -> None:
    # Thesis 4.4.4: UAVs 74 and 112 fly toward each other, three targets; 74 gets target
    # 1 and 112 target 2 (the thesis numbers targets from 1; indices here are 0-based).
    # The thesis gives no times: these are illustrative ones with that outcome, chosen so
    # that 112's own best target (index 0) is taken first by 74's even shorter time.
    results: Results = {74: [20.0, 45.0, 90.0], 112: [22.0, 30.0, 60.0]}
    a = greedy_assign(results, 3)
    assert a == Assignment(pairs={74: 0, 112: 1}, unassigned_targets=(2,), idle_uavs=())


def test_greedy_is_not_optimal_by_design() -> None:
    # The rule is the thesis's, not a min-sum assignment: 1->0 then 2->1 totals 101 s
    # where 1->1, 2->0 totals 4 s. Every UAV must reproduce the rule, not improve on it.
    assert greedy_assign({1: [1.0, 2.0], 2: [2.0, 100.0]}, 2).pairs == {1: 0, 2: 1}


def test_more_uavs_than_targets_leaves_idle_uavs() -> None:
    a = greedy_assign({1: [5.0], 2: [4.0], 3: [6.0]}, 1)
    assert a.pairs == {2: 0}
    assert a.idle_uavs == (1, 3)


def test_none_and_nan_and_inf_are_never_assigned() -> None:
    results: Results = {1: [None, math.nan], 2: [math.inf, -math.inf]}
    a = greedy_assign(results, 2)
    assert a == Assignment(pairs={}, unassigned_targets=(0, 1), idle_uavs=(1, 2))
    # Around usable times too: -inf must not win, +inf must not stop the sweep early.
    a = greedy_assign({1: [-math.inf, 5.0], 2: [math.nan, math.inf], 3: [1.0, math.inf]}, 2)
    assert a == Assignment(pairs={1: 1, 3: 0}, unassigned_targets=(), idle_uavs=(2,))


def test_uav_whose_only_answer_is_taken_stays_idle() -> None:
    a = greedy_assign({1: [1.0, None], 2: [2.0, None]}, 2)
    assert a.pairs == {1: 0}
    assert a.idle_uavs == (2,)
    assert a.unassigned_targets == (1,)


def test_empty_inputs() -> None:
    assert greedy_assign({}, 3) == Assignment({}, (0, 1, 2), ())
    assert greedy_assign({5: [], 4: []}, 0) == Assignment({}, (), (4, 5))


def test_row_of_wrong_length_names_the_uav() -> None:
    with pytest.raises(ValueError, match=r"UAV 112: expected 3 .* got 2"):
        greedy_assign({74: [1.0, 2.0, 3.0], 112: [1.0, 2.0]}, 3)


def test_negative_target_count_is_refused() -> None:
    with pytest.raises(ValueError, match="n_targets"):
        greedy_assign({}, -1)


def test_accepts_tuples_as_rows() -> None:
    # UavResult.times arrives as a tuple.
    assert greedy_assign({3: (2.0, None), 4: (1.0, 5.0)}, 2).pairs == {4: 0}


# --- digest -------------------------------------------------------------------------


def test_digest_ignores_order_and_sequence_type() -> None:
    results: Results = {112: [30.0, None, 35.5], 74: [25.0, 40.0, None]}
    expected = results_digest(results)
    assert len(expected) == 16
    int(expected, 16)  # hex
    assert results_digest({74: [25.0, 40.0, None], 112: [30.0, None, 35.5]}) == expected
    assert results_digest({74: (25.0, 40.0, None), 112: (30.0, None, 35.5)}) == expected


def test_digest_pinned_value() -> None:
    # If this changes, UAVs running different builds can no longer confirm each other's
    # input: the byte layout documented in fleet.consensus.assignment must stay fixed.
    assert results_digest({74: [1.0, None]}) == "850a8d010f61ebc0"


@given(st.floats(allow_nan=False, allow_infinity=False))
def test_digest_sensitive_to_one_ulp(time: float) -> None:
    up = math.nextafter(time, math.inf)
    assert results_digest({1: [time]}) != results_digest({1: [up]})


def test_digest_distinguishes_none_zero_and_negative_zero() -> None:
    digests = {
        results_digest({1: [None]}),
        results_digest({1: [0.0]}),
        results_digest({1: [-0.0]}),
        results_digest({1: []}),
        results_digest({}),
    }
    assert len(digests) == 5


def test_digest_distinguishes_which_uav_said_what() -> None:
    assert results_digest({1: [1.0], 2: [2.0]}) != results_digest({1: [2.0], 2: [1.0]})
    # Row boundaries are hashed: the same flat sequence split differently differs.
    assert results_digest({1: [1.0, 2.0], 2: []}) != results_digest({1: [1.0], 2: [2.0]})


def test_digest_is_bit_exact_for_nan_payloads() -> None:
    quiet = struct.unpack("<d", struct.pack("<Q", 0x7FF8000000000000))[0]
    other = struct.unpack("<d", struct.pack("<Q", 0x7FF8000000000001))[0]
    assert results_digest({1: [quiet]}) != results_digest({1: [other]})


# --- the implementation before the faster one, kept as its reference ---------------


def _reference_greedy_assign(
    results: Mapping[int, Sequence[float | None]], n_targets: int
) -> Assignment:
    """greedy_assign as it was written before its sweep and its keys were made faster."""
    uavs = sorted(results)
    keys = [math.inf if t is None or t != t else t for uav in uavs for t in results[uav]]
    order = sorted(range(len(keys)), key=keys.__getitem__)
    pairs: dict[int, int] = {}
    taken_targets: set[int] = set()
    max_pairs = min(len(uavs), n_targets)
    for k in order:
        if len(pairs) == max_pairs:
            break
        time = keys[k]
        if time == math.inf:
            break
        if time == -math.inf:
            continue
        rank, target = divmod(k, n_targets)
        uav = uavs[rank]
        if uav in pairs or target in taken_targets:
            continue
        pairs[uav] = target
        taken_targets.add(target)
    return Assignment(
        pairs={uav: pairs[uav] for uav in sorted(pairs)},
        unassigned_targets=tuple(t for t in range(n_targets) if t not in taken_targets),
        idle_uavs=tuple(sorted(uav for uav in results if uav not in pairs)),
    )


def _reference_digest(results: Mapping[int, Sequence[float | None]]) -> str:
    """results_digest as it was written before its times were packed all at once."""
    parts = [b"fleet.assignment.results/v1\x00"]
    for uav in sorted(results):
        row = results[uav]
        parts.append(struct.pack("<qQ", uav, len(row)))
        parts += [b"N" if time is None else b"T" + struct.pack("<d", time) for time in row]
    return hashlib.sha256(b"".join(parts)).hexdigest()[:16]


def _random_case(rng: random.Random) -> tuple[dict[int, Sequence[float | None]], int]:
    """Teams and missions up to 60 x 60: model-like times, ties, and now and then None,
    NaN (any payload), the infinities, -0.0 and negative times; rows as tuples or lists."""
    n_targets = rng.choice((0, 1, 2, rng.randint(1, 60)))
    uavs = rng.sample(range(1, 0xFFF1), rng.choice((0, 1, rng.randint(1, 60))))
    odd = rng.random() < 0.5  # half the cases are all finite times, as the model gives

    def time() -> float | None:
        if odd and rng.random() < 0.1:
            nan = struct.unpack("<d", struct.pack("<Q", 0x7FF8000000000000 | rng.getrandbits(20)))
            return rng.choice((None, math.inf, -math.inf, -0.0, 0.0, -5.0, nan[0]))
        if rng.random() < 0.05:
            return float(rng.randint(0, 3))  # ties
        return rng.uniform(20.0, 900.0)

    results: dict[int, Sequence[float | None]] = {}
    for uav in uavs:
        row = [time() for _ in range(n_targets)]
        results[uav] = tuple(row) if rng.random() < 0.5 else row
    return results, n_targets


def test_equal_to_the_previous_implementation_on_random_cases() -> None:
    rng = random.Random(20261125)
    for _ in range(1000):
        results, n_targets = _random_case(rng)
        fast = greedy_assign(results, n_targets)
        reference = _reference_greedy_assign(results, n_targets)
        assert fast == reference
        assert list(fast.pairs) == list(reference.pairs)
        assert results_digest(results) == _reference_digest(results)


# --- each row prepared as its result arrives (fleet.consensus.result_rows) -----------


@given(results_strategy(), st.randoms(use_true_random=False))
def test_rows_prepared_beforehand_give_the_same_pairs_and_digest(
    case: tuple[Results, int], rnd: random.Random
) -> None:
    """Orders and digest bytes computed beforehand for some UAVs (the rest computed in
    the call) give exactly the assignment and the digest of the times alone."""
    results, n_targets = case
    some = [uav for uav in results if rnd.random() < 0.7]
    orders = {uav: row_order(results[uav]) for uav in some}
    packed = {uav: row_bytes(uav, results[uav]) for uav in some}
    assert greedy_assign(results, n_targets, orders) == greedy_assign(results, n_targets)
    assert greedy_assign(results, n_targets, orders).pairs == reference_greedy(results, n_targets)
    assert results_digest(results, rows_bytes=packed) == results_digest(results)
    assert results_digest(results, b"zones", packed) == results_digest(results, b"zones")


def test_a_rows_order_is_its_usable_targets_by_time_then_index() -> None:
    assert row_order([3.0, None, 1.0, math.nan, 3.0, -0.0, math.inf, 0.0, -math.inf]) == (
        5,
        7,
        2,
        0,
        4,
    )
    assert row_order(()) == ()


def test_equal_to_the_previous_implementation_with_rows_prepared() -> None:
    rng = random.Random(20261126)
    for _ in range(300):
        results, n_targets = _random_case(rng)
        orders = {uav: row_order(row) for uav, row in results.items()}
        packed = {uav: row_bytes(uav, row) for uav, row in results.items()}
        assert greedy_assign(results, n_targets, orders) == _reference_greedy_assign(
            results, n_targets
        )
        assert results_digest(results, rows_bytes=packed) == _reference_digest(results)
