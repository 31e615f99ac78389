"""Which teammates are present (their liveliness tokens), and who stayed gone too long.

Before the commitment the consensus leaves a gone teammate out at once; after it, a
teammate is released (its target re-planned) only once it stayed gone past the grace.
"""

from __future__ import annotations

from dataclasses import dataclass, field

#: A committed teammate whose liveliness token stays gone this long (s) is released. A
#: router failover withdraws every token learned through the dead router and declares
#: it again through the surviving path some milliseconds later: releasing at once
#: re-planned both UAVs of a two-router mesh apart, each without the other.
LIVELINESS_GRACE_S = 2.0


@dataclass
class TeamPresence:
    uav_id: int
    #: A committed teammate gone from liveliness this long is released (LIVELINESS_GRACE_S).
    grace_s: float = LIVELINESS_GRACE_S
    alive: set[int] = field(default_factory=set)
    _gone_since: dict[int, float] = field(default_factory=dict)  #: liveliness lost, when

    def __post_init__(self) -> None:
        self.alive.add(self.uav_id)

    def came(self, uav: int) -> bool:
        """`uav`'s token is present; True if it was not."""
        new = uav not in self.alive
        self.alive.add(uav)
        self._gone_since.pop(uav, None)
        return new

    def went(self, uav: int, now: float, *, committed: bool) -> bool:
        """`uav`'s token went; True if it is to be released once past the grace (this UAV
        `committed` already)."""
        if uav == self.uav_id:
            return False
        self.alive.discard(uav)
        if committed:
            self._gone_since.setdefault(uav, now)
        return committed

    def gone_past_grace(self, now: float) -> list[int]:
        """The teammates gone past the grace, each given once."""
        gone = [uav for uav, since in self._gone_since.items() if now - since >= self.grace_s]
        for uav in gone:
            del self._gone_since[uav]
        return gone
