"""Counting refused links from Zenoh's log: the classifier on lines captured from a real
secure router (Zenoh 1.10), the tap that reads a file descriptor, and the watch."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from fleet.transport import refusal_watch
from fleet.transport.fd_tap import MAX_LINE, FdTap
from fleet.transport.link_refusal import LinkRefusal, RefusedLinks, classify
from fleet.transport.refusal_watch import RefusalWatch
from tests.support.waiting import wait_until

_TLS = (
    "\x1b[2m2026-11-26T02:13:49.037176Z\x1b[0m \x1b[33m WARN\x1b[0m acc-0 ThreadId(05) "
    "\x1b[2mzenoh_link_tls::unicast\x1b[0m\x1b[2m:\x1b[0m "
)
_HINT = ". Hint: increase the system open file limit."
#: What a secure router logged when each kind of client was refused (RUST_LOG colours).
CAPTURED = {
    _TLS + "peer sent no certificates" + _HINT: LinkRefusal.NO_CERTIFICATE,
    _TLS + "invalid peer certificate: BadSignature" + _HINT: LinkRefusal.UNKNOWN_CA,
    _TLS + "invalid peer certificate: UnknownIssuer" + _HINT: LinkRefusal.UNKNOWN_CA,
    _TLS + "invalid peer certificate: certificate expired: verification time 1795659232 (UNIX), "
    "but certificate is not valid after 1795657425 (1807 seconds ago)" + _HINT: LinkRefusal.EXPIRED,
    _TLS + "invalid peer certificate: NotValidForName" + _HINT: LinkRefusal.BAD_CERTIFICATE,
    _TLS + "received fatal alert: DecryptError" + _HINT: LinkRefusal.PEER_REFUSED,
    _TLS + "tls handshake eof" + _HINT: LinkRefusal.TLS_OTHER,  # a bare TCP connect
    _TLS + "received corrupt message of type InvalidContentType" + _HINT: LinkRefusal.TLS_OTHER,
    "\x1b[2m2026-11-26T02:14:13.216763Z\x1b[0m \x1b[32m INFO\x1b[0m acc-0 ThreadId(05) "
    "\x1b[2mzenoh::net::routing::interceptor::access_control\x1b[0m\x1b[2m:\x1b[0m "
    "5d9261ad8ca9695d45c7949da220e01a did not match any configured ACL subject. Default "
    "permission `Deny` will be applied on all messages": LinkRefusal.NO_RIGHTS,
}
NOT_REFUSALS = [
    "2026-11-26 02:13:45,189 __main__ INFO zenoh router 2619adce listening on tls/127.0.0.1:1",
    "2026-11-26T02:16:21.388516Z  INFO ThreadId(01) zenoh::net::runtime: Using ZID: 4073",
    # A client's own failure to connect is not the router refusing a link.
    "2026-11-26T02:15:59.766132Z  WARN ThreadId(01) zenoh::net::runtime::orchestrator: Unable "
    "to connect to tls/127.0.0.1:47111! received fatal alert: CertificateRequired",
    # The watch's own totals, and a TLS module line below warning level.
    "2026-11-26 02:16:45,005 fleet.transport.refusal_watch WARNING refused links so far: "
    "no_certificate=1",
    "2026-11-26T02:16:21Z DEBUG zenoh_link_tls::unicast: peer sent no certificates",
    "",
    "\x1b[33m garbage \xff\x00",
]


@pytest.mark.parametrize(("line", "kind"), CAPTURED.items())
def test_each_captured_refusal_is_classified(line: str, kind: LinkRefusal) -> None:
    assert classify(line) is kind


@pytest.mark.parametrize("line", NOT_REFUSALS)
def test_other_lines_are_not_refusals(line: str) -> None:
    assert classify(line) is None


def test_counts_by_kind_in_a_fixed_order() -> None:
    links = RefusedLinks()
    assert links.counts() == {} and links.summary() == "none"
    assert links.count(LinkRefusal.EXPIRED) == 1
    links.count(LinkRefusal.NO_CERTIFICATE)
    assert links.count(LinkRefusal.EXPIRED) == 2
    assert links.counts() == {"no_certificate": 1, "expired": 2}
    assert links.summary() == "no_certificate=1 expired=2"


def test_the_tap_passes_every_byte_on_and_hands_over_lines(tmp_path: Path) -> None:
    out = tmp_path / "out"
    fd = os.open(out, os.O_WRONLY | os.O_CREAT)
    lines: list[str] = []
    tap = FdTap(lines.append, fd)
    try:
        tap.start()
        os.write(fd, b"one\ntw")
        os.write(fd, b"o\n\xffbad\n" + b"x" * (MAX_LINE + 10))
        os.write(fd, b"\nlast, with no newline")
    finally:
        tap.stop()
    os.write(fd, b"!")  # after stop(): straight to the file again
    os.close(fd)
    long = "x" * (MAX_LINE + 10)
    assert out.read_bytes() == b"one\ntwo\n\xffbad\n" + long.encode() + b"\nlast, with no newline!"
    assert lines[:3] == ["one", "two", "\ufffdbad"]
    assert "".join(lines[3:-1]) == long  # cut, but every byte handed over
    assert lines[-1] == "last, with no newline"


def test_a_failing_reader_does_not_stop_the_output(tmp_path: Path) -> None:
    out = tmp_path / "out"
    fd = os.open(out, os.O_WRONLY | os.O_CREAT)

    def fail(line: str) -> None:
        raise ValueError(line)

    tap = FdTap(fail, fd)
    try:
        tap.start()
        os.write(fd, b"a\nb\n")
    finally:
        tap.stop()
        os.close(fd)
    assert out.read_bytes() == b"a\nb\n"


def test_the_watch_counts_zenohs_lines_on_standard_output(caplog: pytest.LogCaptureFixture) -> None:
    watch = RefusalWatch(report_every_s=0.05)
    watch.start()
    try:
        for line, _ in list(CAPTURED.items())[:2]:
            os.write(1, line.encode() + b"\n")
        wait_until(lambda: sum(watch.links.counts().values()) == 2, 10.0, "two refusals")
        assert watch.links.counts() == {"no_certificate": 1, "unknown_ca": 1}
        wait_until(
            lambda: "refused links so far: no_certificate=1 unknown_ca=1" in caplog.text,
            10.0,
            "the totals in the log",
        )
    finally:
        watch.stop()


def test_with_nothing_to_tap_the_watch_says_so_and_counts_nothing(
    caplog: pytest.LogCaptureFixture,
) -> None:
    closed = os.open(os.devnull, os.O_WRONLY)
    os.close(closed)
    watch = RefusalWatch(fd=closed)
    watch.start()
    watch.stop()
    assert "refused links will not be counted" in caplog.text
    assert watch.links.counts() == {}


def test_one_watch_per_process_while_any_router_uses_it() -> None:
    first = refusal_watch.acquire()
    try:
        assert refusal_watch.acquire() is first
        refusal_watch.release()
        os.write(1, next(iter(CAPTURED)).encode() + b"\n")  # still counted: one user is left
        wait_until(lambda: first.links.counts() == {"no_certificate": 1}, 10.0, "the count")
    finally:
        refusal_watch.release()
    assert refusal_watch.acquire() is not first  # the last release stopped it
    refusal_watch.release()


def test_a_flood_of_refusals_is_counted_whole_and_logged_a_few_times(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    out = os.open(tmp_path / "out", os.O_WRONLY | os.O_CREAT)
    watch = RefusalWatch(report_every_s=0.5, fd=out)
    watch.start()
    try:
        line = next(iter(CAPTURED)).encode() + b"\n"
        for _ in range(10):
            os.write(out, line * 100)
        wait_until(lambda: watch.links.counts() == {"no_certificate": 1000}, 10.0, "1000")
        wait_until(lambda: "no_certificate=1000" in caplog.text, 10.0, "the last totals")
    finally:
        watch.stop()
        os.close(out)
    lines = [r for r in caplog.records if "refused links so far" in r.getMessage()]
    assert 1 <= len(lines) < 100  # one a half-second at most, not one a refusal
    # Counted whole, and not passed on: each is logged at DEBUG (fleet.transport.zenoh_log).
    assert (tmp_path / "out").read_bytes() == b""
