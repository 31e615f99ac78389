"""How a message reached a receiver, which decides who must have signed it and how
fresh it must be (fleet.mission.signature). Its own module, free of `cryptography`, so
that the bus can name it in the open profile without loading OpenSSL."""

from __future__ import annotations

from enum import Enum, auto

__all__ = ["Delivery"]


class Delivery(Enum):
    """How a message reached us: it decides who must have signed it and how fresh."""

    PUT = auto()  #: a publication
    QUERY = auto()  #: a query's payload (a command to a queryable)
    REPLY = auto()  #: a reply to our query: possibly relayed, possibly old
