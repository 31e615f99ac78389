"""A simulated autopilot served over `Link`s instead of sockets or ptys.

`SimServer` serves aircraft on TCP ports and ptys for separate processes; this serves
one aircraft on any `fleet.transport.link.Link`, typically one end of an in-memory pipe
(`fleet.transport.memory.memory_link_pair`) whose other end an onboard process holds,
so both run in one test process. Call `pump` from one thread: it advances simulated
time and moves the bytes both ways.
"""

from __future__ import annotations

from fleet.sim.autopilot import SimulatedAutopilot
from fleet.transport.link import Link


class LinkedAutopilot:
    """One simulated aircraft whose program and payload ports are `Link`s."""

    def __init__(self, autopilot: SimulatedAutopilot, program: Link, payload: Link) -> None:
        self.autopilot = autopilot
        self.program = program
        self.payload = payload
        self.connection = autopilot.open_program("program")

    def pump(self, time_ms: int) -> None:
        """Fly to simulated `time_ms`, then exchange what each side wrote."""
        autopilot = self.autopilot
        autopilot.advance_to(time_ms)
        now = time_ms / 1000.0
        if self.program.ensure_open(now):
            data = self.program.read(now)
            if data:
                autopilot.receive(self.connection, data)
            if len(self.connection.output):
                self.program.write(self.connection.output.take(), now)
        elif len(self.connection.output):
            self.connection.output.take()  # nobody on the line: the bytes are lost
        if self.payload.ensure_open(now):
            data = self.payload.read(now)
            if data:
                autopilot.payload.from_onboard(data)
            if len(autopilot.payload.to_onboard):
                self.payload.write(autopilot.payload.to_onboard.take(), now)
