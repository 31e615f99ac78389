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
