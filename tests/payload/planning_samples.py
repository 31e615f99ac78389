"""Known packets, message strategies and helpers shared by the planning-protocol tests."""

from hypothesis import strategies as st

from fleet.mission.messages import (
    MissionAbort,
    MissionTargets,
    OpmCommand,
    StatusText,
    Target,
    UavResult,
)
from fleet.payload.bodies import (
    PlanningMessage,
    UnknownPlanningMessage,
    status_kind_of_text,
)
from fleet.payload.framing import (
    PAYLOAD_UAV,
)
from fleet.payload.protocol import (
    Envelope,
    PlanningDecoder,
    encode_message,
)

# Thesis 2.9's own example: a PAYLOAD_STATUS "OK" has size two. From Piccolo 112 to
# the Mission Manager, written out byte by byte.
STATUS_OK = bytes(
    [
        0xB5,  # sync
        0x02,  # size: two text bytes, no NUL
        0x01,  # type: PAYLOAD_STATUS
        0x00,  # user: unused for status
        0xFE, 0xFF,  # destination: Mission Manager (0xFFFE, little-endian)
        0x70, 0x00,  # source: Piccolo 112
        0x4F, 0x4B,  # "OK"
    ]
)  # fmt: skip

# UAV 74's result for mission 3: 1.5 s to target 0, no answer for target 1, broadcast.
RESULT_74 = bytes(
    [
        0xB5,  # sync
        0x1C,  # size: 4 segment header + 8 result header + 2 x 8 times = 28
        0x02,  # type: PAYLOAD_UAV
        0x02,  # user: PAYLOAD_UAVRESULT
        0xFF, 0xFF,  # destination: broadcast
        0x4A, 0x00,  # source: Piccolo 74
        0x05, 0x00,  # segment: message seq 5
        0x00,  # segment index 0
        0x01,  # segment count 1
        0x03, 0x00, 0x00, 0x00,  # mission 3 (u32)
        0x4A, 0x00,  # uav 74 (u16)
        0x02, 0x00,  # 2 times (u16)
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF8, 0x3F,  # 1.5 (f64)
        0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xF8, 0x7F,  # NaN: None
    ]
)  # fmt: skip

# The ground aborts mission 7 on every UAV.
ABORT_7 = bytes(
    [
        0xB5, 0x08, 0x02, 0x03,  # sync, size 8, PAYLOAD_UAV, PAYLOAD_ABORT
        0xFF, 0xFF, 0xFE, 0xFF,  # to broadcast, from the Mission Manager
        0x00, 0x00, 0x00, 0x01,  # seq 0, segment 0 of 1
        0x07, 0x00, 0x00, 0x00,  # mission 7
    ]
)  # fmt: skip

addresses = st.integers(0, 0xFFFF)
finite = st.floats(allow_nan=False, allow_infinity=False)
targets = st.builds(
    Target,
    lat=finite,
    lon=finite,
    # Altitude travels as f32 (thesis 4.2): only f32 values come back unchanged.
    alt=st.floats(width=32, allow_nan=False, allow_infinity=False),
)
opm_commands = st.builds(
    OpmCommand,
    enabled=st.booleans(),
    status_rate_hz=st.floats(min_value=0, allow_infinity=False),
)
mission_targets = st.builds(
    MissionTargets,
    mission=st.integers(0, 0xFFFF_FFFF),
    team=st.lists(addresses, max_size=40).map(tuple),
    targets=st.lists(targets, max_size=70).map(tuple),
    deadline_s=st.floats(min_value=0, allow_infinity=False),
)
uav_results = st.builds(
    UavResult,
    mission=st.integers(0, 0xFFFF_FFFF),
    uav=addresses,
    times=st.lists(st.none() | st.floats(allow_nan=False), max_size=100).map(tuple),
)
aborts = st.builds(MissionAbort, mission=st.integers(0, 0xFFFF_FFFF))
unknowns = st.builds(
    UnknownPlanningMessage,
    type=st.just(PAYLOAD_UAV),
    user=st.integers(0, 0xFF).filter(lambda u: u not in (1, 2, 3)),
    body=st.binary(max_size=700),
)
# Short enough (<= 60 code points, <= 240 bytes) to travel as one status packet.
# The link carries the text alone and its edge gives it a kind from its prefix
# ("error...", "warning..."): a round trip keeps that kind, not any other.
short_status = st.text(max_size=60).map(lambda text: StatusText(text, status_kind_of_text(text)))
messages: st.SearchStrategy[PlanningMessage] = st.one_of(
    opm_commands, short_status, mission_targets, uav_results, aborts, unknowns
)
envelopes = st.builds(Envelope, source=addresses, destination=addresses, message=messages)


def wire_of(sent: list[Envelope]) -> bytes:
    # A distinct seq per message, as a sender with several messages in flight must use.
    return b"".join(
        encode_message(e.message, e.source, e.destination, seq=i) for i, e in enumerate(sent)
    )


def no_drops(decoder: PlanningDecoder) -> bool:
    return not any(decoder.drops.values())


def big_mission(n_targets: int = 60, n_team: int = 30, mission: int = 9) -> MissionTargets:
    return MissionTargets(
        mission=mission,
        team=tuple(range(100, 100 + n_team)),
        targets=tuple(Target(42.36 + i * 1e-3, -71.09 - i * 1e-3, 120.5) for i in range(n_targets)),
        deadline_s=12.5,
    )
