"""No-fly zones through the page's server: Load and Save as GeoJSON, and a Send that
carries zones (or is refused for a target inside one, nothing sent). The page's
server in the test's process on the in-process bus with two `FakeOnboard`s
(tests/ground/gui/test_server.py)."""

from __future__ import annotations

import asyncio
import json

from tests.ground.gui.test_server import (  # noqa: F401
    TARGETS,
    _session_with,
    gui,
    memory,
    mfakes,
    post,
)
from tests.support.fake_onboard import FakeOnboard
from tests.support.waiting import wait_until

#: A box beside TARGETS (none inside), and one around TARGETS[0] (42.36, -71.09).
BESIDE = [[-71.080, 42.350], [-71.070, 42.350], [-71.070, 42.355], [-71.080, 42.355]]
AROUND = [[-71.095, 42.355], [-71.085, 42.355], [-71.085, 42.365], [-71.095, 42.365]]


def geojson(ring: list[list[float]]) -> bytes:
    return json.dumps({"type": "Polygon", "coordinates": [[*ring, ring[0]]]}).encode()


def test_zones_are_loaded_and_saved_as_geojson(gui: str) -> None:  # noqa: F811
    status, body = post(f"{gui}/api/zones/import?name=z.geojson", geojson(BESIDE))
    assert status == 200
    zones = json.loads(body)["zones"]
    assert zones[0]["ring"][0] == [42.35, -71.08]
    status, body = post(f"{gui}/api/zones/export", json.dumps(zones).encode())
    assert status == 200 and json.loads(body)["features"][0]["geometry"]["type"] == "Polygon"
    bowtie = [[-71.08, 42.35], [-71.07, 42.355], [-71.07, 42.35], [-71.08, 42.355]]
    status, body = post(f"{gui}/api/zones/import?name=bad.geojson", geojson(bowtie))
    assert status == 400 and b"bad.geojson" in body and b"cross" in body


def test_a_send_carries_the_zones_and_a_target_inside_one_sends_nothing(
    gui: str,  # noqa: F811
    mfakes: dict[int, FakeOnboard],  # noqa: F811
) -> None:
    fakes = mfakes
    targets = [{"lat": t.lat, "lon": t.lon, "alt": t.alt} for t in TARGETS]

    def zone(ring: list[list[float]]) -> dict[str, object]:
        return {"name": "z", "ring": [[lat, lon] for lon, lat in [*ring, ring[0]]]}

    before = len(fakes[74].targets)
    inside, sent = asyncio.run(
        _session_with(
            gui,
            [
                {"cmd": "send", "id": 1, "team": [74, 112], "targets": targets,
                 "zones": [zone(AROUND)]},
                {"cmd": "send", "id": 2, "team": [74, 112], "targets": targets,
                 "zones": [zone(BESIDE)]},
            ],
        )
    )  # fmt: skip
    assert not inside["ok"] and "target 0 is inside no-fly zone 0 (z)" in inside["message"]
    assert "nothing sent" in inside["message"]
    assert sent["ok"] and "and 1 no-fly zones published" in sent["message"]
    assert wait_until(lambda: len(fakes[74].targets) == before + 1)
    assert fakes[74].targets[-1].zones[0].ring[0] == (42.35, -71.08)
