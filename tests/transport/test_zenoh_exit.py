"""Every Zenoh session still open is closed before the interpreter finalizes
(fleet.transport.zenoh_exit): a process that exits with one open, callbacks firing, can
otherwise abort or segfault on its way out (bench/zenoh_exit_crash.py)."""

from __future__ import annotations

import gc
import subprocess
import sys
import weakref

import pytest

from fleet.transport import zenoh_exit
from fleet.transport.router import Router
from fleet.transport.zenoh_bus import ZenohBus, connect
from fleet.transport.zenoh_exit import ExitClosers
from tests.support.processes import ANY_PORT


class Owner:
    def __init__(self, name: str, closed: list[str], fails: bool = False) -> None:
        self.name, self.closed, self.fails = name, closed, fails

    def close(self) -> None:
        self.closed.append(self.name)
        if self.fails:
            raise RuntimeError(f"{self.name} cannot close")


def test_what_is_registered_is_closed_once_the_last_registered_first() -> None:
    closers, closed = ExitClosers(), list[str]()
    router, client = Owner("router", closed), Owner("client", closed)
    closers.add(router.close)
    closers.add(client.close)
    assert len(closers) == 2
    closers.close_all()
    closers.close_all()
    assert closed == ["client", "router"]


def test_an_owner_is_held_weakly_a_dropped_one_is_neither_kept_nor_closed() -> None:
    closers, closed = ExitClosers(), list[str]()
    dropped = Owner("dropped", closed)
    gone = weakref.ref(dropped)
    closers.add(dropped.close)
    del dropped
    gc.collect()
    assert gone() is None
    assert len(closers) == 0
    closers.close_all()
    assert closed == []


def test_a_close_that_fails_leaves_the_others_to_close() -> None:
    closers, closed = ExitClosers(), list[str]()
    first, failing = Owner("first", closed), Owner("failing", closed, fails=True)
    closers.add(first.close)
    closers.add(failing.close)
    closers.close_all()
    assert closed == ["failing", "first"]


def test_a_router_and_a_bus_never_closed_are_closed_by_the_exit_closers(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    closers = ExitClosers()
    monkeypatch.setattr(zenoh_exit, "AT_EXIT", closers)
    router = Router([ANY_PORT])
    router.open()
    bus = connect(router.endpoints[0])
    assert len(closers) == 2
    closers.close_all()
    assert bus.session.is_closed()
    with pytest.raises(RuntimeError, match="not open"):
        router.session  # noqa: B018 - the property raises once closed
    bus.close()  # and closing again is harmless
    router.close()


def test_a_bus_on_someone_elses_session_leaves_it_to_its_owner(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    closers = ExitClosers()
    monkeypatch.setattr(zenoh_exit, "AT_EXIT", closers)
    with Router([ANY_PORT]) as router:
        ZenohBus(router.session, owns_session=False)
        assert len(closers) == 1  # the router's own registration only


CHILD = """
import atexit, sys
# Registered first, so it runs after the closers (atexit runs the last registered first).
atexit.register(lambda: print("closed at exit:", bus.session.is_closed(), router._session))
from fleet.transport.router import Router
from fleet.transport.zenoh_bus import connect
router = Router([sys.argv[1]])
router.open()
bus = connect(router.endpoints[0])
bus.subscribe("k/**", lambda sample: None)
bus.put("k/x", b"x")
"""


@pytest.mark.e2e
def test_a_process_that_exits_with_its_sessions_open_closes_them_first() -> None:
    done = subprocess.run(
        [sys.executable, "-c", CHILD, ANY_PORT],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "closed at exit: True None" in done.stdout, (done.stdout, done.stderr)
