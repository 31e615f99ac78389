"""Which teammates are present, and who stayed gone too long.

A teammate is present while its liveliness token is. A token carries no signature,
though: any router on the way can declare one (a ghost), or replay a real UAV's. So in
the secure profile (`vouch`) a token counts only once the UAV has spoken for itself
since it appeared: its state, signed by its own key, answered this UAV's query (asked
when the token came), or any other message signed by it was heard (its result, its
assignment, its outcome). A ghost token never counts: the team neither waits for a
result from it (until the deadline) nor re-plans with it.

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
    #: Whether a token counts only once its UAV spoke for itself (the secure profile).
    vouch: bool = False
    #: The teammates that count as present (and this UAV itself).
    alive: set[int] = field(default_factory=set)
    #: The tokens present, vouched for or not.
    tokens: set[int] = field(default_factory=set)
    #: The UAVs that spoke for themselves (a signed message) since their token came.
    vouched: set[int] = field(default_factory=set)
    _gone_since: dict[int, float] = field(default_factory=dict)  #: liveliness lost, when

    def __post_init__(self) -> None:
        self.alive.add(self.uav_id)

    def came(self, uav: int) -> bool:
        """`uav`'s token is present; True if it counts now and did not."""
        self.tokens.add(uav)
        if self.vouch and uav != self.uav_id and uav not in self.vouched:
            return False  # a token alone: counted once its UAV speaks for itself
        return self._count(uav)

    def spoke(self, uav: int) -> bool:
        """A message signed by `uav` was heard; True if its token counts now and did not."""
        self.vouched.add(uav)
        return uav in self.tokens and self._count(uav)

    def waiting_for_word(self, uav: int) -> bool:
        """Whether `uav`'s token is present but not counted yet, for lack of its word."""
        return self.vouch and uav in self.tokens and uav not in self.alive

    def _count(self, uav: int) -> bool:
        new = uav not in self.alive
        self.alive.add(uav)
        self._gone_since.pop(uav, None)
        return new

    def went(self, uav: int, now: float, *, committed: bool) -> bool:
        """`uav`'s token went; True if it is to be released once past the grace (this UAV
        `committed` already, and the token counted)."""
        if uav == self.uav_id:
            return False
        self.tokens.discard(uav)
        # Its word was for the token that went: a token declared again needs it again.
        self.vouched.discard(uav)
        # A ghost's token (never counted) going releases nothing.
        counted = uav in self.alive or not self.vouch
        self.alive.discard(uav)
        if committed and counted:
            self._gone_since.setdefault(uav, now)
        return committed and counted

    def gone_past_grace(self, now: float) -> list[int]:
        """The teammates gone past the grace, each given once."""
        gone = [uav for uav, since in self._gone_since.items() if now - since >= self.grace_s]
        for uav in gone:
            del self._gone_since[uav]
        return gone
