"""Tests of the exception root (fleet.errors): every deliberate error is a FleetError."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
from collections.abc import Callable

import pytest

import fleet
import ground
import onboard
from fleet.errors import CodecError, FleetError
from fleet.mission.targets_file import decode_targets
from fleet.payload.framing import encode_packet
from fleet.piccolo.stream_packet import StreamPacket, encode_stream_packet


def _project_exceptions() -> list[type[BaseException]]:
    found = []
    for package in (fleet, onboard, ground):
        for info in pkgutil.walk_packages(package.__path__, f"{package.__name__}."):
            module = importlib.import_module(info.name)
            for _, value in inspect.getmembers(module, inspect.isclass):
                if issubclass(value, BaseException) and value.__module__ == info.name:
                    found.append(value)
    return found


def test_every_project_exception_is_a_fleet_error() -> None:
    exceptions = _project_exceptions()
    assert len(exceptions) > 10
    strays = [
        f"{e.__module__}.{e.__qualname__}" for e in exceptions if not issubclass(e, FleetError)
    ]
    assert strays == []


def test_codec_errors_are_value_errors_too() -> None:
    assert issubclass(CodecError, FleetError)
    assert issubclass(CodecError, ValueError)


@pytest.mark.parametrize(
    ("refusal", "match"),
    [
        (lambda: decode_targets(b"", "t.bin"), "no targets"),
        (lambda: encode_packet(0, 0, 0, 0, bytes(256)), "payload is 256 bytes"),
        (lambda: encode_stream_packet(StreamPacket(0, 0, 0, 0, 300, b"")), "stream 300"),
    ],
)
def test_codec_refusals_are_caught_as_codec_and_value_errors(
    refusal: Callable[[], object], match: str
) -> None:
    with pytest.raises(CodecError, match=match):
        refusal()
    with pytest.raises(ValueError, match=match):
        refusal()
