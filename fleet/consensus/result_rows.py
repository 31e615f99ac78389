"""What a decision needs of each teammate's result, computed as the result arrives.

At N = 50 every UAV decides within the same few milliseconds of the last result (issue
28's consensus window): fifty processes on the same cores. Whatever depends on one
result alone is therefore done when that result arrives, spread over the planning time
before the last one: each row's greedy order (`row_order`) and its bytes in the results
digest (`row_bytes`). The decision then only merges the orders and hashes the bytes,
and reaches exactly what it would from the times alone (the same pairs, the same digest
on every UAV).

Pure: no I/O.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

from fleet.consensus.assignment import row_bytes, row_order


@dataclass(frozen=True, slots=True)
class ResultRow:
    """One UAV's times, with their greedy order and their digest bytes."""

    times: Sequence[float | None]
    order: tuple[int, ...]
    packed: bytes


@dataclass
class ResultRows:
    """Each UAV's latest `ResultRow`, kept for the times it was computed from."""

    rows: dict[int, ResultRow] = field(default_factory=dict)

    def add(self, uav: int, times: Sequence[float | None]) -> ResultRow:
        row = ResultRow(times, row_order(times), row_bytes(uav, times))
        self.rows[uav] = row
        return row

    def of(self, uav: int, times: Sequence[float | None]) -> ResultRow:
        """`uav`'s row for exactly these times: computed now if `add` was given others
        (or none), so a stale row is never used."""
        row = self.rows.get(uav)
        return row if row is not None and row.times is times else self.add(uav, times)

    def orders(self, used: Mapping[int, Sequence[float | None]]) -> dict[int, tuple[int, ...]]:
        return {uav: self.of(uav, times).order for uav, times in used.items()}

    def packed(self, used: Mapping[int, Sequence[float | None]]) -> dict[int, bytes]:
        return {uav: self.of(uav, times).packed for uav, times in used.items()}
