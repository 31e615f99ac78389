"""The thesis's deterministic greedy target assignment (section 4.4.3).

Every UAV runs this function on the same set of results and must reach the same pairs
without a coordinator, so the rule is a *total* order on the candidate triples

    (approach time, Piccolo ID, target index), lowest first.

The thesis orders by approach time, then by lowest Piccolo ID; the target index is the
last key so that one UAV tied between two targets still picks deterministically. The
greedy then repeatedly takes the first remaining triple and drops every other triple of
that UAV or that target (thesis steps 3-4): one sweep over the sorted list, computed as
a merge of each UAV's row in its own order (`row_order`, prepared as each result arrives).

Approach times are seconds. ``None`` means the UAV has no answer for that target (its
model failed or timed out); NaN and the infinities are treated the same way, because
neither compares meaningfully and an infinite approach time means "unreachable". Such
entries are never assigned. Any finite float, including a negative one, is ordered as
is: the rule is well defined on it, and judging physical plausibility belongs to the
approach-time model, not to the consensus. Times compare as floats, so -0.0 and 0.0 are
a tie (broken by Piccolo ID), while the digest below tells them apart.

`results_digest` lets UAVs confirm, bit for bit, that they ran the rule on the same
input before acting on the result.
"""

from __future__ import annotations

import functools
import heapq
import math
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import cast

from fleet.consensus.digest import sha256

__all__ = [
    "Assignment",
    "air_bytes",
    "greedy_assign",
    "proposes_bytes",
    "results_digest",
    "row_bytes",
    "row_order",
    "time_or_inf",
    "usable",
]


@dataclass(frozen=True, slots=True)
class Assignment:
    """The outcome of `greedy_assign`.

    `pairs` maps Piccolo ID -> target index, in increasing Piccolo ID order.
    `unassigned_targets` are target indices no UAV was given, ascending.
    `idle_uavs` are Piccolo IDs left without a target (more UAVs than targets, or no
    usable answer left for them), ascending.
    """

    pairs: dict[int, int]
    unassigned_targets: tuple[int, ...]
    idle_uavs: tuple[int, ...]


def row_order(row: Sequence[float | None]) -> tuple[int, ...]:
    """The targets `row` has a usable (finite) time to, by (time, target index): one UAV's
    candidates in the greedy's order. A `MissionRound` computes it as each result
    arrives, so that the decision only merges the rows (`greedy_assign`'s `orders`)."""
    # A finite sum means no None (TypeError), NaN or infinity: one C-level pass.
    try:
        finite = math.isfinite(sum(cast(Sequence[float], row)))
    except TypeError:
        finite = False
    indices = range(len(row)) if finite else [t for t, time in enumerate(row) if usable(time)]
    # Stable on the time alone (every one kept is a float): equal times keep the lower
    # target index first.
    return tuple(sorted(indices, key=cast(Sequence[float], row).__getitem__))


def usable(time: float | None) -> bool:
    """A finite approach time (None, NaN and the infinities are no answer)."""
    return time is not None and math.isfinite(time)


def time_or_inf(time: float | None) -> float:
    """The time where usable, else +inf: no answer sorts after every answer."""
    return time if time is not None and math.isfinite(time) else math.inf


def greedy_assign(
    results: Mapping[int, Sequence[float | None]],
    n_targets: int,
    orders: Mapping[int, Sequence[int]] | None = None,
) -> Assignment:
    """Assign targets to UAVs by the thesis's greedy rule, ties broken by a total order.

    `results[uav][i]` is UAV `uav`'s approach time (s) to target `i`, or None when it has
    no answer. `orders[uav]`, where given, must be `row_order(results[uav])` (computed
    beforehand, off the decision's path); the others are computed here. Raises
    ValueError if `n_targets` is negative or a row does not have exactly `n_targets`
    entries (the message names the UAV).
    """
    if n_targets < 0:
        raise ValueError(f"n_targets must be >= 0, got {n_targets}")
    for uav, row in results.items():
        if len(row) != n_targets:
            raise ValueError(
                f"UAV {uav}: expected {n_targets} approach times (one per target), got {len(row)}"
            )

    # The sweep over every (time, Piccolo ID, target index) triple in order, taking each
    # whose UAV and target are both free, is a merge of the UAVs' rows, each in its own
    # order (`row_order`): a heap holds each free UAV's first candidate whose target was
    # free when it was pushed, keyed (time, rank) with UAVs ranked by increasing Piccolo
    # ID, so the least entry is the sweep's next triple a free UAV could take. Its target
    # taken since, the UAV moves on to its next free target; a UAV that took a target
    # leaves the heap. The sweep itself visited the taken UAVs' entries too (50 x 50:
    # ~2,200 of 2,500); the merge pops about one entry per pair.
    uavs = sorted(results)
    rows = [results[uav] for uav in uavs]
    ranked = [
        orders[uav] if orders is not None and uav in orders else row_order(row)
        for uav, row in zip(uavs, rows, strict=True)
    ]
    heap = [(rows[rank][order[0]], rank, 0) for rank, order in enumerate(ranked) if order]
    heapq.heapify(heap)
    pairs: dict[int, int] = {}
    target_free = [True] * n_targets
    max_pairs = min(len(uavs), n_targets)
    while heap and len(pairs) < max_pairs:
        _, rank, position = heap[0]
        order = ranked[rank]
        target = order[position]
        if target_free[target]:
            target_free[target] = False
            pairs[uavs[rank]] = target
            heapq.heappop(heap)
            continue
        position += 1
        while position < len(order) and not target_free[order[position]]:
            position += 1
        if position < len(order):
            heapq.heapreplace(heap, (rows[rank][order[position]], rank, position))
        else:
            heapq.heappop(heap)

    return Assignment(
        pairs={uav: pairs[uav] for uav in sorted(pairs)},
        unassigned_targets=tuple(t for t in range(n_targets) if target_free[t]),
        idle_uavs=tuple(uav for uav in uavs if uav not in pairs),
    )


# Digest layout, fixed so that every implementation hashes the same bytes:
#   per UAV in increasing Piccolo ID order: '<q' Piccolo ID, '<Q' row length, then per
#   entry either b'T' + '<d' time (the exact IEEE-754 bits, so -0.0, NaN payloads and
#   1-ulp differences all change the digest) or b'N' for None.
# The row length is hashed so that rows of different lengths can never run together.
_DIGEST_VERSION = b"fleet.assignment.results/v1\x00"
_HEADER = struct.Struct("<qQ")
_TIME = struct.Struct("<d")
#   then, per UAV whose result says how it flies (fleet.consensus.legs.Air), in increasing
#   Piccolo ID order: `air_bytes`: b'air\0', '<q' Piccolo ID, then per number (airspeed,
#   wind east, wind north, lat, lon) b'T' + '<d' or b'N' for None;
#   then, per UAV whose result says whether it will propose a plan (UavResult.proposes),
#   in increasing Piccolo ID order: `proposes_bytes`: b'proposes\0', '<q' Piccolo ID,
#   b'Y' or b'N';
#   then, for a mission with no-fly zones only: b'zones\0', '<Q' their length, their bytes.
_ZONES_TAG = b"zones\x00"
_ZONES_LENGTH = struct.Struct("<Q")
_AIR_TAG = b"air\x00"
_AIR_UAV = struct.Struct("<q")
_PROPOSES_TAG = b"proposes\x00"


def results_digest(
    results: Mapping[int, Sequence[float | None]],
    zones: bytes = b"",
    rows_bytes: Mapping[int, bytes] | None = None,
    air: Mapping[int, bytes] | None = None,
    proposes: Mapping[int, bytes] | None = None,
) -> str:
    """A stable 16-hex-digit digest (SHA-256 prefix) of exactly these results.

    Independent of the mapping's insertion order; sensitive to every bit of every time,
    and to the mission's no-fly zones (`zones`: fleet.mission.no_fly.zones_bytes; none,
    the digest of the results alone). `rows_bytes[uav]`, where given, must be
    `row_bytes(uav, results[uav])` (computed as the result arrived); the others are
    packed here. `air[uav]`: `air_bytes` of its result (none, or empty: it says nothing,
    and the digest is the one of its times alone). `proposes[uav]`: `proposes_bytes` of
    its result (none, or empty: it does not say).
    """
    given = rows_bytes if rows_bytes is not None else {}
    parts = [_DIGEST_VERSION]
    parts += [
        given[uav] if uav in given else row_bytes(uav, results[uav]) for uav in sorted(results)
    ]
    if air:
        parts += [air[uav] for uav in sorted(results) if air.get(uav)]
    if proposes:
        parts += [proposes[uav] for uav in sorted(results) if proposes.get(uav)]
    if zones:
        parts += [_ZONES_TAG, _ZONES_LENGTH.pack(len(zones)), zones]
    # One buffer hashed once: the same bytes as an update per field, in a third of the
    # time (50 x 50 results: ~0.3 ms instead of ~0.9 ms, on every UAV at every commit).
    return sha256(b"".join(parts)).hexdigest()[:16]


def air_bytes(uav: int, numbers: Sequence[float | None]) -> bytes:
    """What `results_digest` hashes of how `uav` flies (its airspeed, wind and position:
    `numbers`); empty if every one is None."""
    if all(number is None for number in numbers):
        return b""
    entries = [b"N" if n is None else b"T" + _TIME.pack(n) for n in numbers]
    return _AIR_TAG + _AIR_UAV.pack(uav) + b"".join(entries)


def proposes_bytes(uav: int, proposes: bool | None) -> bytes:
    """What `results_digest` hashes of whether `uav` will propose a plan; empty if its
    result does not say."""
    if proposes is None:
        return b""
    return _PROPOSES_TAG + _AIR_UAV.pack(uav) + (b"Y" if proposes else b"N")


def row_bytes(uav: int, row: Sequence[float | None]) -> bytes:
    """What `results_digest` hashes of `uav`'s row: its header, then its entries."""
    # One C-level pack of the header and every (b'T', time) pair (50 times: ~1.7 us,
    # a third of packing the times and interleaving their markers apart); only a row
    # holding a None (struct.error: nearly never) is written entry by entry.
    count = len(row)
    fields: list[bytes | float | None] = [b"T"] * (2 * count)
    fields[1::2] = row
    try:
        return _row_struct(count).pack(uav, count, *fields)
    except struct.error:
        entries = [b"N" if time is None else b"T" + _TIME.pack(time) for time in row]
        return _HEADER.pack(uav, count) + b"".join(entries)


@functools.lru_cache(maxsize=64)
def _row_struct(count: int) -> struct.Struct:
    """A row's header and `count` tagged times, as one struct."""
    return struct.Struct("<qQ" + "cd" * count)
