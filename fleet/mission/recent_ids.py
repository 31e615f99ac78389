"""A set of mission ids that input cannot grow without bound.

A process remembers some ids a message named (the missions aborted, ...). Each message
may name a new one, so a stream of them, hostile or just long, would grow a plain set
forever (100,000 aborts: 2.8 MB, never trimmed). `RecentIds` keeps the highest `limit`
ids: mission ids only increase, so the ones dropped are the oldest, which no newer
mission can need.
"""

from __future__ import annotations

from collections.abc import Iterator

#: Far more missions than any fleet has pending at once.
DEFAULT_LIMIT = 1024


class RecentIds:
    """The highest `limit` ids added (at most 2 x `limit` held between trims)."""

    def __init__(self, limit: int = DEFAULT_LIMIT) -> None:
        if limit < 1:
            raise ValueError("a RecentIds keeps at least one id")
        self.limit = limit
        self._ids: set[int] = set()

    def add(self, mission: int) -> None:
        self._ids.add(mission)
        if len(self._ids) > 2 * self.limit:
            # Trimmed in batches: sorting once per `limit` additions, not on each.
            self._ids = set(sorted(self._ids)[-self.limit :])

    def __contains__(self, mission: object) -> bool:
        return mission in self._ids

    def __len__(self) -> int:
        return len(self._ids)

    def __iter__(self) -> Iterator[int]:
        return iter(self._ids)
