"""Targets and checks shared by the targets codec and targets file tests."""

from __future__ import annotations

import re
import struct

from hypothesis import strategies as st

from fleet.mission.messages import Target
from fleet.mission.targets_file import ALTITUDE_ENVELOPE_M, TARGET_SIZE, TargetsFileError

targets_lists = st.lists(
    st.builds(
        Target,
        lat=st.floats(min_value=-90.0, max_value=90.0),
        lon=st.floats(min_value=-180.0, max_value=180.0),
        alt=st.floats(min_value=ALTITUDE_ENVELOPE_M[0], max_value=ALTITUDE_ENVELOPE_M[1]),
    ),
    min_size=1,
    max_size=20,
).filter(
    # A list whose every byte is printable is refused as text by design (tested on its
    # own in test_targets_file); Hypothesis finds such floats, so round trips skip them.
    lambda targets: (
        not all(
            0x20 <= byte < 0x7F or byte in (0x09, 0x0A, 0x0D)
            for byte in b"".join(struct.pack("<3d", t.lat, t.lon, t.alt) for t in targets)
        )
    )
)

BOSTON = Target(lat=42.3601, lon=-71.0942, alt=120.0)
HANSCOM = Target(lat=42.4700, lon=-71.2890, alt=133.0)


def raw(*records: tuple[float, float, float]) -> bytes:
    return b"".join(struct.pack("<3d", *r) for r in records)


def names_file_index_offset(err: TargetsFileError, source: str, index: int) -> None:
    message = str(err)
    assert source in message
    assert re.search(rf"\btarget {index}\b", message), message
    assert f"byte offset {index * TARGET_SIZE}" in message
    assert (err.source, err.index, err.offset) == (source, index, index * TARGET_SIZE)
