"""A UAV's streams (telemetry, track, waypoint echoes, status, link health), authenticated
by their author at the cost of one signature per half second, not one per sample.

Signing each sample would cost a UAV 20+ signatures a second and the ground 20 x N
checks (about 150 us each: at N=50, a core's sixth); unsigned, a router holding a UAV
router's key could show the ground an aircraft where it is not, a status it never sent
or an aircraft that does not exist. So the sender (`StreamSigner`) hashes every sample it
puts on its own stream keys (BLAKE2b-128 of key and payload) and every DIGEST_EVERY_S
puts the list of those hashes, signed like any other message, on its `digest` key. The
receiver (`StreamChecker`) holds each stream sample until a digest of its author lists it
(a sample arriving after its digest finds the hash waiting), then delivers it; a sample
no digest vouches for within HOLD_S is dropped and counted (`unverified`). Each hash is
used once per receiver (a subscription: one sample reaches every subscription of a bus
it matches, and each is owed it once) and forgotten after HOLD_S: a sample replayed
later is never believed.

The price: a stream sample reaches the ground up to DIGEST_EVERY_S (plus transit) late.
"""

from __future__ import annotations

import hashlib
import logging
import threading
import time
from collections import Counter, OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass

from fleet.mission.messages import MAX_DIGEST_SAMPLES, StreamDigest
from fleet.mission.signature import Refusal
from fleet.transport import bus_codec

log = logging.getLogger(__name__)

#: How often (s) a UAV puts the digest of what it streamed since the last.
DIGEST_EVERY_S = 0.5
#: How long (s) a sample waits for its digest, and a digest's hash for its sample.
HOLD_S = 3.0
#: Samples held, and hashes kept, across all authors (the oldest go first).
MAX_HELD = 8192


def sample_hash(key: str, payload: bytes) -> str:
    """What a digest lists for one sample: its key and payload, hashed (hex)."""
    digest = hashlib.blake2b(key.encode(), digest_size=16)
    digest.update(b"\0")
    digest.update(payload)
    return digest.hexdigest()


class StreamSigner:
    """The sender's side: the hashes of its stream samples, put as a signed digest every
    DIGEST_EVERY_S while it streams (`put_digest(key, message)` signs and puts it)."""

    def __init__(
        self, put_digest: Callable[[str, StreamDigest], None], every_s: float = DIGEST_EVERY_S
    ) -> None:
        self._put_digest = put_digest
        self._every_s = every_s
        self._lock = threading.Lock()
        #: The digest key (a UAV's, under a prefix) -> that UAV and the hashes to list.
        self._pending: dict[str, tuple[int, list[str]]] = {}
        self._timer: threading.Timer | None = None
        self._closed = False

    def streamed(self, digest_key: str, uav: int, key: str, payload: bytes) -> None:
        """A sample UAV `uav` put on its stream `key`: in its next digest (`digest_key`)."""
        hashed = sample_hash(key, payload)
        with self._lock:
            if self._closed:
                return
            pending = self._pending.setdefault(digest_key, (uav, []))[1]
            pending.append(hashed)
            full = len(pending) >= MAX_DIGEST_SAMPLES
            if self._timer is None and not full:
                self._timer = threading.Timer(self._every_s, self.flush)
                self._timer.daemon = True
                self._timer.start()
        if full:
            self.flush()

    def flush(self) -> None:
        """Put the digest of every sample streamed since the last one."""
        with self._lock:
            pending, self._pending = self._pending, {}
            timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()
        for digest_key, (uav, hashes) in pending.items():
            try:
                self._put_digest(digest_key, StreamDigest(uav, hashes))
            except Exception:  # a closed session: the digest is lost, as the samples are
                log.debug("could not put %s", digest_key, exc_info=True)

    def close(self) -> None:
        with self._lock:
            self._closed = True
            timer, self._timer = self._timer, None
        if timer is not None:
            timer.cancel()


@dataclass
class _Held:
    author: str
    hashed: str
    deliver: Callable[[], None]
    since: float
    receiver: int


@dataclass
class _Credit:
    """A hash a digest listed: when, how many times (two samples may be the same bytes),
    and how many of those each receiver has used."""

    since: float
    times: int
    used: Counter[int]

    def take(self, receiver: int) -> bool:
        if self.used[receiver] >= self.times:
            return False
        self.used[receiver] += 1
        return True


class StreamChecker:
    """The receiver's side: stream samples held until their author's digest lists them."""

    def __init__(self, clock: Callable[[], float] = time.monotonic, hold_s: float = HOLD_S) -> None:
        self._clock = clock
        self._hold_s = hold_s
        self._lock = threading.Lock()
        self._held: deque[_Held] = deque()
        #: (author, hash) -> what a digest listed, for samples still to come.
        self._vouched: OrderedDict[tuple[str, str], _Credit] = OrderedDict()
        self.unverified = 0

    def hold(
        self,
        author: str,
        key: str,
        payload: bytes,
        deliver: Callable[[], None],
        receiver: int = 0,
    ) -> None:
        """A sample on `author`'s stream `key` heard by `receiver`: `deliver` is called
        once a digest of `author` lists it (at once if one already did), never if none
        does in time."""
        hashed = sample_hash(key, payload)
        now = self._clock()
        with self._lock:
            self._expire(now)
            credit = self._vouched.get((author, hashed))
            ready = credit is not None and credit.take(receiver)
            if not ready:
                self._held.append(_Held(author, hashed, deliver, now, receiver))
                while len(self._held) > MAX_HELD:
                    self._drop(self._held.popleft())
        if ready:
            deliver()

    def vouch(self, author: str, digest: StreamDigest) -> None:
        """`author`'s signed digest: deliver the samples it lists (in arrival order), and
        keep the rest of its hashes for samples still on their way."""
        now = self._clock()
        ready: list[Callable[[], None]] = []
        with self._lock:
            self._expire(now)
            credits: dict[str, _Credit] = {}
            for hashed, times in Counter(digest.hashes).items():
                credit = self._vouched.pop((author, hashed), None)
                if credit is None:
                    credit = _Credit(now, 0, Counter())
                credit.since, credit.times = now, credit.times + times
                credits[hashed] = self._vouched[(author, hashed)] = credit
            kept: deque[_Held] = deque()
            for held in self._held:
                credit = credits.get(held.hashed) if held.author == author else None
                if credit is not None and credit.take(held.receiver):
                    ready.append(held.deliver)
                else:
                    kept.append(held)
            self._held = kept
            while len(self._vouched) > MAX_HELD:
                self._vouched.popitem(last=False)
        for deliver in ready:
            deliver()

    def _expire(self, now: float) -> None:
        while self._held and now - self._held[0].since > self._hold_s:
            self._drop(self._held.popleft())
        while self._vouched and now - next(iter(self._vouched.values())).since > self._hold_s:
            self._vouched.popitem(last=False)

    def _drop(self, held: _Held) -> None:
        self.unverified += 1
        bus_codec.DROPPED.add(Refusal.UNVERIFIED)
        if self.unverified <= 10 or self.unverified % 1000 == 0:
            log.warning(
                "dropped a sample of %s's streams no digest of its vouched for (%d so far)",
                held.author,
                self.unverified,
            )
