"""How urgently each fleet message travels on Zenoh: priority and congestion control.

Each key's `Urgency` is declared in the key registry (`fleet.mission.key_registry`);
this maps it to Zenoh's QoS. Mission traffic (targets, results, assignments, aborts
under `{prefix}/mission/`) and the ground's commands (`{prefix}/uav/{id}/opm`) must
never queue behind telemetry: they go at INTERACTIVE_HIGH priority (a queue of its own,
served before the others) and BLOCK (never dropped when a queue is full). They are not
express: when the fifty UAVs of a team commit together, the router batches the fifty
assignment reports it fans out to each subscriber instead of writing them one by one,
each waking the subscriber's receiving thread (measured at N = 50 while every UAV still
subscribed to its teammates' commitments, last result -> last commit 115-186 ms express,
71-103 ms batched; a batch waits at most Zenoh's batching time limit, 1 ms by default).
Telemetry goes at DATA_LOW and DROP: a stale sample is worth nothing when the next
follows within a second. Everything else keeps Zenoh's defaults (DATA, DROP).
"""

from __future__ import annotations

from dataclasses import dataclass

import zenoh

from fleet.mission.key_registry import Urgency
from fleet.mission.key_space import KeySpace, space_of
from fleet.transport.bus_codec import ENCODING


@dataclass(frozen=True)
class Qos:
    priority: zenoh.Priority
    congestion_control: zenoh.CongestionControl
    express: bool


URGENT = Qos(zenoh.Priority.INTERACTIVE_HIGH, zenoh.CongestionControl.BLOCK, False)
TELEMETRY = Qos(zenoh.Priority.DATA_LOW, zenoh.CongestionControl.DROP, False)
ORDINARY = Qos(zenoh.Priority.DATA, zenoh.CongestionControl.DROP, False)


_QOS = {Urgency.URGENT: URGENT, Urgency.TELEMETRY: TELEMETRY, Urgency.ORDINARY: ORDINARY}


def qos_for(key: str, space: KeySpace | None = None) -> Qos:
    """The priority and congestion control of a publication on `key`: ORDINARY for a key
    the registry does not know under `space`'s prefix.

    Without `space`, the key's own prefix (its first chunk) is taken: a process publishes
    under its own prefix only, so it is the process's.
    """
    space = space or space_of(key)
    parsed = space.parse(key) if space is not None else None
    return _QOS[parsed.spec.urgency] if parsed is not None else ORDINARY


def put(
    session: zenoh.Session,
    key: str,
    payload: bytes,
    qos: Qos | None = None,
    attachment: bytes | None = None,
) -> None:
    """Publish bus-codec `payload` on `key` with the key's priority and congestion control
    (`qos`, when the caller already looked it up), and `attachment` (a signature)."""
    qos = qos or qos_for(key)
    session.put(
        key,
        payload,
        encoding=ENCODING,
        attachment=attachment,
        priority=qos.priority,
        congestion_control=qos.congestion_control,
        express=qos.express,
    )


def declare(session: zenoh.Session, key: str, qos: Qos | None = None) -> zenoh.Publisher:
    """A publisher of bus-codec payloads on `key`, with the key's priority and congestion
    control: for a key put at a steady rate."""
    qos = qos or qos_for(key)
    return session.declare_publisher(
        key,
        encoding=ENCODING,
        priority=qos.priority,
        congestion_control=qos.congestion_control,
        express=qos.express,
    )
