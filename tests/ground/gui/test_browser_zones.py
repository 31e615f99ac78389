"""No-fly zones on the Mission Manager's page in a real browser against a real fleet
(`fleet up head_on --gui`, Debian's headless Chromium through Selenium; the fixtures and
helpers are tests/ground/gui/test_browser.py's): a zones file loaded, a zone drawn by
clicking the map, both drawn and sent with the mission, and the assigned UAV's planned
route around them drawn."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

from tests.ground.gui.test_browser import (  # noqa: F401
    TargetsSeen,
    browser,
    click_at,
    fleet_with_gui,
    pytestmark,
    text_of,
    zoom_out,
)
from tests.support.processes import client_session
from tests.support.waiting import wait_until

pytestmark = pytestmark

#: A wall north of both aircraft's racetracks, 12 km wide: a target beyond it is reached
#: around one of its ends.
WALL = ((35.745, -120.83), (35.745, -120.70), (35.75, -120.70), (35.75, -120.83))
BEYOND = (35.76, -120.765)
#: A small zone loaded from a file, out of everyone's way.
LOADED = [[-120.86, 35.69], [-120.85, 35.69], [-120.85, 35.695], [-120.86, 35.695]]


def load_zones(driver: Any, name: str, data: bytes) -> None:
    """Choose a file in the zones' Load input, as the file dialog does."""
    driver.execute_script(
        """
        const [name, bytes] = arguments;
        const transfer = new DataTransfer();
        transfer.items.add(new File([new Uint8Array(bytes)], name));
        const input = document.querySelector('#load-zones');
        input.files = transfer.files;
        input.dispatchEvent(new Event('change', {bubbles: true}));
        """,
        name,
        list(data),
    )


def count(driver: Any, selector: str) -> int:
    found: int = driver.execute_script(
        "return document.querySelectorAll(arguments[0]).length", selector
    )
    return found


def test_zones_loaded_and_drawn_are_sent_drawn_and_flown_around(
    fleet_with_gui: tuple[str, str],  # noqa: F811
    browser: Any,  # noqa: F811
    tmp_path: Path,
) -> None:
    url, router = fleet_with_gui
    with client_session(router) as session:
        sent = TargetsSeen(session)
        try:
            browser.get(url)
            wait_until(lambda: count(browser, "#map g.uav") == 2, 30.0, "both UAVs drawn")
            polygon = {"type": "Polygon", "coordinates": [[*LOADED, LOADED[0]]]}
            load_zones(browser, "zones.geojson", json.dumps(polygon).encode())
            wait_until(lambda: count(browser, "#layer-zones polygon") == 1, 10.0, "zone loaded")
            assert "1 no-fly zone(s) loaded" in text_of(browser, "notice")

            # A zone drawn by clicking the map: Draw zone, four corners, Finish zone.
            zoom_out(browser)
            browser.find_element("id", "draw-zone").click()
            for lat, lon in WALL:
                click_at(browser, lat, lon)
            assert "4 vertices" in browser.find_element("id", "draw-zone").text
            browser.find_element("id", "draw-zone").click()
            wait_until(lambda: count(browser, "#layer-zones polygon") == 2, 10.0, "zone drawn")
            assert count(browser, "#zone-list li") == 2
            assert count(browser, "#map [data-target]") == 0  # the clicks made no target

            click_at(browser, *BEYOND)
            wait_until(lambda: count(browser, "#map [data-target]") == 1, 10.0, "the target")
            browser.find_element("id", "send").click()
            browser.find_element("id", "confirm-ok").click()
            wait_until(lambda: bool(sent.missions), 30.0, "the mission on the bus")
            (mission,) = sent.missions
            assert len(mission.zones) == 2
            drawn = mission.zones[1].ring
            assert len(drawn) == 5 and drawn[0] == drawn[-1]
            assert all(
                abs(a - b) < 0.003
                for p, q in zip(drawn, WALL, strict=False)
                for a, b in zip(p, q, strict=True)
            )

            # The UAV assigned the target flies a route around the wall: drawn on the map.
            wait_until(
                lambda: count(browser, "#layer-routes polyline") == 1, 60.0, "the planned route"
            )
            points = browser.execute_script(
                "return document.querySelector('#layer-routes polyline').getAttribute('points')"
            )
            assert len(points.split()) >= 3  # the UAV, at least one turn, the target
            time.sleep(0.5)
            browser.save_screenshot(str(tmp_path / "zones.png"))
        finally:
            sent.subscriber.undeclare()
