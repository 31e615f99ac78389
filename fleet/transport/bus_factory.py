"""One place every program opens its bus: `open_bus(spec)`.

Like python-can's `can.Bus(interface=...)`: the spec says which backend, the caller gets
a `Bus` and never names one. A spec is

* a Zenoh config, or one Zenoh endpoint (`tcp/127.0.0.1:7447`): a client session
  (`fleet.transport.zenoh_bus.connect`, which fails fast and clearly when nothing answers);
* `memory:NAME`: a participant of the in-process network NAME (`fleet.transport.memory`),
  made on first use; every bus opened on one name sees the others, with no socket.

`faults` wraps either in the fault-injecting bus (`fleet.transport.faulty_bus`).

A program opens its bus here once, at its root, and hands it to its command
(`fleet.transport.command`); nothing below a root opens a session of its own. The
backends are imported only when a bus of theirs is opened, so a program that only
prints its usage never loads Zenoh's session machinery.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TYPE_CHECKING

from fleet.transport.bus import (
    Bus,
    DelegatingBus,
    RingSubscription,
)

if TYPE_CHECKING:
    import zenoh

    from fleet.transport.faulty_bus import FaultRule
    from fleet.transport.memory import MemoryNetwork

    #: What `open_bus` takes: a Zenoh config, a Zenoh endpoint, or `memory:NAME`.
    BusSpec = str | zenoh.Config

#: The prefix of an in-process bus's spec.
MEMORY_SCHEME = "memory:"
#: How long opening a Zenoh session may take against an endpoint that accepts but never
#: answers (`fleet.transport.zenoh_bus.DEFAULT_OPEN_TIMEOUT_S`).
OPEN_TIMEOUT_S = 3.0

_networks: dict[str, MemoryNetwork] = {}
_networks_lock = threading.Lock()


def is_memory_spec(spec: object) -> bool:
    """Whether `spec` names an in-process bus (`memory:NAME`)."""
    return isinstance(spec, str) and spec.startswith(MEMORY_SCHEME)


def memory_network(name: str) -> MemoryNetwork:
    """The in-process network `name` (made on first use): what `memory:NAME` joins."""
    from fleet.transport.memory import MemoryNetwork

    with _networks_lock:
        network = _networks.get(name)
        if network is None:
            network = _networks[name] = MemoryNetwork()
        return network


def forget_memory_network(name: str) -> None:
    """Drop the network `name`: the next `memory:NAME` starts an empty one."""
    with _networks_lock:
        _networks.pop(name, None)


def open_bus(
    spec: BusSpec,
    *,
    faults: Sequence[FaultRule] = (),
    open_timeout_s: float = OPEN_TIMEOUT_S,
) -> Bus:
    """A bus as `spec` says (module docstring); the caller closes it.

    Raises BusConnectError (`fleet.transport.zenoh_bus`) if no Zenoh router answers or
    the endpoint is malformed, ValueError for `memory:` with no name.
    """
    bus: Bus
    if isinstance(spec, str) and is_memory_spec(spec):
        name = spec.removeprefix(MEMORY_SCHEME)
        if not name:
            raise ValueError(f"{spec!r}: an in-process bus needs a name, e.g. memory:test")
        bus = memory_network(name).bus()
    else:
        from fleet.transport.zenoh_bus import connect

        bus = connect(spec, open_timeout_s=open_timeout_s)
    if faults:
        from fleet.transport.faulty_bus import FaultyBus

        bus = FaultyBus(bus, *faults)
    return bus


@contextmanager
def opened_bus(
    spec: BusSpec,
    *,
    faults: Sequence[FaultRule] = (),
    open_timeout_s: float = OPEN_TIMEOUT_S,
) -> Iterator[Bus]:
    """`open_bus` as a context manager: the bus is always closed."""
    bus = open_bus(spec, faults=faults, open_timeout_s=open_timeout_s)
    try:
        yield bus
    finally:
        bus.close()


class OnFirstUse(DelegatingBus):
    """The bus `opener` opens, opened when a command first uses it, closed with it.

    A program's root hands this to its command: a command first does what needs no
    fleet (reads and checks its files, opens its own port, or finds it needs no bus at
    all, like `fleet record --recover`), so a bad file or a taken port is said before
    connecting, and without a router. The opener's error (no router, a bad Zenoh config)
    comes out of that first use.
    """

    def __init__(self, opener: Callable[[], Bus]) -> None:
        self._opener = opener
        self._bus: Bus | None = None
        self._lock = threading.Lock()

    @property
    def opened(self) -> Bus:
        """The bus, opened now if it was not yet."""
        with self._lock:
            if self._bus is None:
                self._bus = self._opener()
            return self._bus

    def put(self, key: str, payload: bytes) -> None:
        self.opened.put(key, payload)

    @property
    def under(self) -> Bus:
        return self.opened

    def subscribe_ring(self, key_expr: str, limit: int) -> RingSubscription:
        return self.opened.subscribe_ring(key_expr, limit)

    def close(self) -> None:
        with self._lock:
            bus, self._bus = self._bus, None
        if bus is not None:
            bus.close()


def unwrap(bus: Bus) -> Bus:
    """The bus under an `OnFirstUse` (opened now), else `bus` itself."""
    return bus.opened if isinstance(bus, OnFirstUse) else bus
