"""Autopilot commands: confirmed by their echo, retried, superseded, or reported failed."""

from __future__ import annotations

from fleet.mission.messages import CommandResult
from fleet.piccolo.track import Track
from fleet.piccolo.waypoint import Waypoint
from onboard.autopilot_commands import AutopilotCommand, CommandTracker, echo_confirms

WAYPOINT = Waypoint(index=90, next_index=0, lat=35.72, lon=-120.76, alt=600.0)


def tracker() -> tuple[CommandTracker, list[AutopilotCommand], list[CommandResult]]:
    sent: list[AutopilotCommand] = []
    results: list[CommandResult] = []
    return CommandTracker(send=sent.append, retry_interval=0.5, max_attempts=3), sent, results


def test_an_echo_confirms_and_nothing_is_resent() -> None:
    commands, sent, results = tracker()
    commands.submit(WAYPOINT, 0.0, results.append)
    assert sent == [WAYPOINT] and commands.pending == 1
    commands.on_echo(WAYPOINT, 0.1)
    assert results == [CommandResult(True, "confirmed by the autopilot", 1)]
    commands.tick(10.0)
    assert sent == [WAYPOINT] and commands.pending == 0


def test_no_echo_is_retried_then_reported_failed() -> None:
    commands, sent, results = tracker()
    commands.submit(Track(90), 0.0, results.append)
    commands.tick(0.4)  # before the retry interval: nothing
    assert len(sent) == 1
    commands.tick(0.5)
    commands.tick(1.0)
    assert sent == [Track(90)] * 3 and not results
    commands.tick(1.5)
    assert results == [CommandResult(False, "no echo after 3 attempts", 3)]
    assert commands.pending == 0


def test_an_echo_of_something_else_does_not_confirm() -> None:
    commands, _, results = tracker()
    commands.submit(WAYPOINT, 0.0, results.append)
    commands.on_echo(Track(90), 0.1)
    commands.on_echo(Waypoint(index=90, next_index=0, lat=35.73, lon=-120.76, alt=600.0), 0.1)
    assert not results and commands.pending == 1


def test_echo_is_compared_as_the_wire_holds_it() -> None:
    # Altitude travels in whole metres: 600.2 m comes back as 600 m and still confirms.
    assert echo_confirms(WAYPOINT, Waypoint(90, 0, 35.72, -120.76, 600.2))
    assert not echo_confirms(Track(90), Track(91))
    assert not echo_confirms(WAYPOINT, Track(90))


def test_a_newer_command_for_the_same_target_supersedes() -> None:
    commands, _, results = tracker()
    first: list[CommandResult] = []
    commands.submit(Track(1), 0.0, first.append)
    commands.submit(Track(2), 0.1, results.append)
    assert first == [CommandResult(False, "superseded", 1)]
    commands.on_echo(Track(2), 0.1)
    assert results[0].ok and commands.pending == 0


def test_cancel_all_reports_each_pending_command() -> None:
    commands, _, results = tracker()
    commands.submit(Track(1), 0.0, results.append)
    commands.submit(WAYPOINT, 0.0, results.append)
    commands.cancel_all("mission aborted")
    assert [r.detail for r in results] == ["mission aborted", "mission aborted"]
    assert commands.pending == 0


def test_cancel_where_ends_only_the_commands_it_picks() -> None:
    commands, sent, results = tracker()
    commands.submit(WAYPOINT, 0.0, results.append, persistent=True)
    other = Waypoint(index=3, next_index=4, lat=35.7, lon=-120.7, alt=600.0)
    commands.submit(other, 0.0, results.append)
    commands.cancel_where(lambda c: isinstance(c, Waypoint) and c.index == 90, "reached")
    assert results == [CommandResult(False, "reached", 1)] and commands.pending == 1
    commands.tick(0.5)
    assert sent[-1] == other
