"""The Mission Manager's page in a real browser against a real fleet.

`fleet up head_on --gui` (router, simulator, two onboard processes and `ground-cli gui`,
all real processes on loopback), and Debian's headless Chromium driven by Selenium
through Debian's chromedriver (never a downloaded browser). The operator's thesis
scenario from the page alone: a malformed file dropped on Load is refused and nothing
is sent; every UAV is drawn where its telemetry says; targets are added by clicking the
map; Send Targets; the assignment lines appear; the targets turn reached; Abort. The
screenshot taken mid-mission is kept in the test's tmp dir (and shown in docs/gui.md).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Callable, Iterator
from importlib.resources import files
from pathlib import Path
from typing import Any

import msgspec
import pytest
import zenoh

from fleet.files.targets_io import read_targets, write_targets
from fleet.geo.mercator import MercatorProjection
from fleet.mission.key_space import KeySpace
from fleet.mission.messages import MissionAbort, MissionTargets, Target
from ground.gui.server import MAX_UPLOAD
from tests.support.ground_cli import ground_cli
from tests.support.ground_view import GroundView
from tests.support.processes import (
    ANY_PAGE,
    ANY_PORT,
    Child,
    client_session,
    start_fleet_up,
    stop_fleet_up,
    wait_fleet_up,
)
from tests.support.waiting import wait_until

webdriver = pytest.importorskip("selenium.webdriver")
from selenium.webdriver.chrome.service import Service  # noqa: E402
from selenium.webdriver.common.action_chains import ActionChains  # noqa: E402
from selenium.webdriver.common.actions.wheel_input import ScrollOrigin  # noqa: E402
from selenium.webdriver.common.by import By  # noqa: E402
from selenium.webdriver.common.keys import Keys  # noqa: E402
from selenium.webdriver.support.select import Select  # noqa: E402

SPACE = KeySpace()

CHROMIUM = "/usr/bin/chromium"
CHROMEDRIVER = "/usr/bin/chromedriver"
#: Where every UAV's icon must be: on the track its telemetry reported, within this (m).
ON_TRACK_M = 60.0
#: Wall seconds for the UAVs to reach their targets at speedup 10 (simulated ~170 s).
REACH_TIMEOUT_S = 120.0

#: Targets added to the thesis scenario's mission in flight, between its own.
ADDED = [(35.7050, -120.7600), (35.7350, -120.7850)]

PROPOSAL_VERDICT = "return document.querySelector('#proposal').dataset.verdict || null;"
#: The plans the UAVs committed to, as the Mission box lists them under the proposals.
COMMITTED_PLANS = (
    "return [...document.querySelectorAll('#proposals li[data-plan]')].map(li => li.textContent);"
)

#: Whether the Mission table's remove button of a target is shown.
REMOVE_SHOWN = """
const b = document.querySelector(`#mission-targets [data-remove-target='${arguments[0]}']`);
return Boolean(b) && getComputedStyle(b).visibility === 'visible';
"""

#: Set by .ci/run, which installs both: there a missing browser fails the tests, not skips.
REQUIRE_BROWSER = "FLEET_REQUIRE_BROWSER"

pytestmark = [
    pytest.mark.e2e,
    pytest.mark.skipif(
        not (Path(CHROMIUM).exists() and Path(CHROMEDRIVER).exists())
        and not os.environ.get(REQUIRE_BROWSER),
        reason=f"no {CHROMIUM} / {CHROMEDRIVER}: `apt-get install chromium chromium-driver` "
        "(.ci/run does it when missing)",
    ),
]

#: The page's map elements, read in one script (the page redraws them at every push).
READ_MAP = """
return [...document.querySelectorAll(
    '#map [data-uav], #map [data-target], #map [data-mission-target]')].map(e => {
  const box = (e.querySelector('.body') || e).getBoundingClientRect();
  return {tag: e.tagName, cls: e.getAttribute('class'), ...e.dataset,
          x: box.x + box.width / 2, y: box.y + box.height / 2};
});
"""


@pytest.fixture
def fleet_with_gui(tmp_path: Path) -> Iterator[tuple[str, str]]:
    """`fleet up head_on --gui`: (the page's URL, the router's endpoint)."""
    up = start_fleet_up(
        "head_on",
        "--listen",
        ANY_PORT,
        "--speedup",
        "10",
        "--gui",
        ANY_PAGE,
        "--log-dir",
        str(tmp_path / "logs"),
    )
    try:
        banner = wait_fleet_up(up, 120.0)
        assert banner.page is not None, "\n".join(up.history[-30:])
        _wait_serving(banner.page, up)
        yield banner.page, banner.connect
    finally:
        assert stop_fleet_up(up) == 0, "\n".join(up.history[-30:])


def _wait_serving(url: str, up: Child) -> None:
    deadline = time.monotonic() + 30.0
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(url, timeout=2) as response:
                if response.status == 200:
                    return
        except OSError:
            time.sleep(0.2)
    raise AssertionError("the page was never served:\n" + "\n".join(up.history[-30:]))


@pytest.fixture
def browser(tmp_path: Path) -> Iterator[Any]:
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in (
        "--headless=new", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
        "--disable-component-update", "--disable-sync", "--no-first-run",
        "--window-size=1500,900", f"--user-data-dir={tmp_path / 'chromium-profile'}",
    ):  # fmt: skip
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(CHROMEDRIVER), options=options)
    try:
        yield driver
    finally:
        driver.quit()


class TargetsSeen:
    """Every MissionTargets put on the bus (to prove that nothing was sent)."""

    def __init__(self, session: zenoh.Session) -> None:
        self.lock = threading.Lock()
        self.missions: list[MissionTargets] = []
        self.subscriber = session.declare_subscriber(SPACE.all_mission_targets, self.on_sample)

    def on_sample(self, sample: zenoh.Sample) -> None:
        message = msgspec.json.decode(sample.payload.to_bytes(), type=MissionTargets)
        with self.lock:
            self.missions.append(message)


def wait_for(driver: Any, what: str, predicate: Callable[[list[dict[str, Any]]], bool],
             timeout: float) -> list[dict[str, Any]]:  # fmt: skip
    """Read the map until `predicate` holds; fails with what the map showed last."""
    deadline = time.monotonic() + timeout
    elements: list[dict[str, Any]] = []
    while time.monotonic() < deadline:
        elements = driver.execute_script(READ_MAP)
        if predicate(elements):
            return elements
        time.sleep(0.2)
    raise AssertionError(f"timed out after {timeout} s waiting for {what}; map: {elements}")


def text_of(driver: Any, element_id: str) -> str:
    """An element's text read in one script call: the page re-renders often, and an
    element found first and read after may be gone by then (StaleElementReference)."""
    text: str = driver.execute_script(
        "const e = document.getElementById(arguments[0]); return e ? e.innerText : '';",
        element_id,
    )
    return text


def uav_icons(elements: list[dict[str, Any]]) -> dict[int, dict[str, Any]]:
    return {int(e["uav"]): e for e in elements if e["cls"] == "uav"}


def target_marks(elements: list[dict[str, Any]]) -> dict[int, dict[str, Any]]:
    return {int(e["target"]): e for e in elements if e["cls"] == "target"}


def mission_marks(elements: list[dict[str, Any]]) -> dict[int, dict[str, Any]]:
    """The followed mission's targets (drawn apart from the drafts), by index."""
    return {int(e["missionTarget"]): e for e in elements if e["cls"] == "target mission-target"}


def assignment_lines(elements: list[dict[str, Any]]) -> dict[int, int]:
    return {int(e["uav"]): int(e["targetIndex"]) for e in elements if e["cls"] == "assignment"}


def drop_file(driver: Any, name: str, data: bytes) -> None:
    """Drop a file on the Load zone, as a drag from the desktop does."""
    driver.execute_script(
        """
        const [name, bytes] = arguments;
        const transfer = new DataTransfer();
        transfer.items.add(new File([new Uint8Array(bytes)], name));
        document.querySelector('#targets-panel').dispatchEvent(
            new DragEvent('drop', {dataTransfer: transfer, bubbles: true, cancelable: true}));
        """,
        name,
        list(data),
    )


def zoom_out(driver: Any) -> None:
    """One wheel step out; returns when the view stopped changing (wheel events can
    arrive spread over time)."""
    svg = driver.find_element(By.ID, "map")
    ActionChains(driver).scroll_from_origin(ScrollOrigin.from_element(svg), 0, 200).perform()
    read = "return document.querySelector('#map').getAttribute('viewBox')"
    before = driver.execute_script(read)
    while True:
        time.sleep(0.3)
        now = driver.execute_script(read)
        if now == before:
            return
        before = now


def click_at(driver: Any, lat: float, lon: float) -> None:
    """Zoom out until (lat, lon) is on the map, then click it."""
    svg = driver.find_element(By.ID, "map")
    for _ in range(10):
        point = driver.execute_script("return window.fleetMap.toClient(...arguments)", lat, lon)
        box = driver.execute_script("return arguments[0].getBoundingClientRect()", svg)
        x, y = point["x"] - box["x"], point["y"] - box["y"]
        if 60 < x < box["width"] - 60 and 80 < y < box["height"] - 80:
            break
        zoom_out(driver)
    else:
        raise AssertionError(f"({lat}, {lon}) never came into view")
    # Selenium offsets are from the element's centre.
    ActionChains(driver).move_to_element_with_offset(
        svg, round(x - box["width"] / 2), round(y - box["height"] / 2)
    ).click().perform()


def contrast(driver: Any, element_id: str) -> float:
    """The WCAG contrast ratio of an element's text against its own background."""
    colours = driver.execute_script(
        "const s = getComputedStyle(document.getElementById(arguments[0]));"
        "return [s.color, s.backgroundColor];",
        element_id,
    )

    def luminance(css: str) -> float:
        channels = [int(c) / 255.0 for c in re.findall(r"\d+", css)[:3]]
        linear = [c / 12.92 if c <= 0.03928 else ((c + 0.055) / 1.055) ** 2.4 for c in channels]
        return 0.2126 * linear[0] + 0.7152 * linear[1] + 0.0722 * linear[2]

    light, dark = sorted((luminance(colours[0]), luminance(colours[1])), reverse=True)
    return (light + 0.05) / (dark + 0.05)


def distance_m(a: tuple[float, float], b: tuple[float, float]) -> float:
    return math.hypot(*MercatorProjection(*a).to_xy(*b))


def test_the_thesis_scenario_from_the_page(
    fleet_with_gui: tuple[str, str], browser: Any, tmp_path: Path
) -> None:
    url, router = fleet_with_gui
    thesis_targets = read_targets(str(files("fleet") / "scenarios" / "head_on_targets.bin"))
    with client_session(router) as session:
        seen = GroundView(session)
        sent = TargetsSeen(session)
        try:
            browser.get(url)
            # Every UAV, drawn where its telemetry says.
            elements = wait_for(
                browser, "both UAVs on the map", lambda e: set(uav_icons(e)) == {74, 112}, 30.0
            )
            for uav, icon in uav_icons(elements).items():
                where = browser.execute_script(
                    "return window.fleetMap.toLatLon(...arguments)", icon["x"], icon["y"]
                )
                assert seen.closest_approach(uav, where["lat"], where["lon"]) < ON_TRACK_M
                assert icon["link"] == "ok" and icon["module"] == "on"

            # A malformed file dropped on Load: refused with its message, nothing sent.
            drop_file(browser, "bad.bin", b"\x00" * 25)
            error = browser.find_element(By.ID, "load-error")
            deadline = time.monotonic() + 10
            while not error.is_displayed() and time.monotonic() < deadline:
                time.sleep(0.1)
            assert "bad.bin: target 1 at byte offset 24" in error.text
            assert "nothing loaded" in error.text
            assert not target_marks(browser.execute_script(READ_MAP))
            # The header's notice says so too, and can be read: not red on red.
            assert "Load refused" in text_of(browser, "notice")
            assert contrast(browser, "notice") >= 4.5

            # The thesis's three targets, by clicking the map (zoomed out: a view that
            # no longer follows the fleet, so the clicks land where they are aimed).
            zoom_out(browser)
            for target in thesis_targets:
                click_at(browser, target.lat, target.lon)
            marks = target_marks(
                wait_for(browser, "3 targets", lambda e: len(target_marks(e)) == 3, 10.0)
            )
            for index, target in enumerate(thesis_targets):
                mark = marks[index]
                assert mark["state"] == "draft"
                clicked = (float(mark["lat"]), float(mark["lon"]))
                assert distance_m(clicked, (target.lat, target.lon)) < 50.0

            # Send Targets, confirming the team and the count.
            browser.find_element(By.ID, "send").click()
            question = text_of(browser, "confirm-text")
            assert "3 target(s)" in question and "74, 112" in question
            assert "3 targets for 2 UAV(s): each UAV queues several" in text_of(
                browser, "confirm-warning"
            )
            assert not sent.missions, "sent before the operator confirmed"
            browser.find_element(By.ID, "confirm-ok").click()

            # The lines are what the UAVs committed on the bus (the thesis's greedy gives
            # 74 target 0 and 112 target 1 when sent early; later, the aircraft have moved).
            def committed_uavs() -> set[int]:
                with seen.lock:
                    return set(seen.assignments)

            wait_until(lambda: committed_uavs() == {74, 112}, 60.0, "both commitments")
            with seen.lock:
                committed = {uav: r.target for uav, r in seen.assignments.items()}
            assigned = {uav: t for uav, t in committed.items() if t is not None}
            elements = wait_for(
                browser, "the assignment lines", lambda e: assignment_lines(e) == assigned, 30.0
            )
            assert [m.team for m in sent.missions] == [(74, 112)]
            # The drafts sent are the mission's targets now: drawn as the mission's, apart.
            assert not target_marks(elements)
            states = {i: m["state"] for i, m in mission_marks(elements).items()}
            assert "unserved" not in states.values()  # the third is queued
            # The queued target is drawn as its holder's tour, its predicted arrival beside it.
            later = set(range(3)) - set(assigned.values())
            elements = wait_for(
                browser,
                "the tour to the queued target",
                lambda e: {int(x["targetIndex"]) for x in e if x["cls"] == "tour"} == later,
                30.0,
            )
            # Read in one script: the page redraws its labels at every push.
            labels = browser.execute_script(
                "return [...document.querySelectorAll('#map .tour-label')].map(l => l.textContent)"
            )
            assert labels and all("ETA" in label for label in labels)
            wait_until(
                lambda: "agreed" in text_of(browser, "agreement"), 10.0, "the agreement shown"
            )
            browser.save_screenshot(str(tmp_path / "gui.png"))

            # The mission changed in flight: two targets, one clicked on the map and one
            # typed, added, done only once both UAVs planned the new revision; then the
            # last removed from its row in the Mission table.
            click_at(browser, *ADDED[0])
            typed = browser.find_element(By.ID, "add-at-text")
            typed.send_keys(f"{ADDED[1][0]}, {ADDED[1][1]}", Keys.ENTER)
            marks = target_marks(
                wait_for(browser, "2 drafts", lambda e: len(target_marks(e)) == 2, 10.0)
            )
            assert (float(marks[1]["lat"]), float(marks[1]["lon"])) == ADDED[1]
            browser.find_element(By.ID, "add-to-mission").click()
            assert "Add 2 target(s) to mission" in text_of(browser, "confirm-text")
            browser.find_element(By.ID, "confirm-ok").click()
            added = wait_command_answered(browser, "add-targets", 60.0)
            assert added["state"] == "done", added
            assert "targets 3, 4 added; acknowledged by 74, 112" in added["text"], added

            def revisions() -> set[int]:
                with seen.lock:
                    return {r.revision for r in seen.assignments.values()}

            wait_until(lambda: revisions() == {1}, 10.0, "both UAVs' plans of revision 1")
            wait_for(browser, "5 mission targets", lambda e: len(mission_marks(e)) == 5, 30.0)
            wait_until(
                lambda: browser.execute_script(REMOVE_SHOWN, 4), 30.0, "target 4's remove button"
            )
            browser.find_element(
                By.CSS_SELECTOR, "#mission-targets [data-remove-target='4']"
            ).click()
            assert "Remove target 4" in text_of(browser, "confirm-text")
            browser.find_element(By.ID, "confirm-ok").click()
            removed = wait_command_answered(browser, "remove-targets", 60.0)
            assert removed["state"] == "done", removed
            assert "target 4 removed; acknowledged by 74, 112" in removed["text"], removed
            assert [(m.revision, m.removed) for m in sent.missions] == [(0, ()), (1, ()), (2, (4,))]

            wait_for(
                browser,
                "every target reached, the queued and added ones too, the removed one not",
                lambda e: (
                    {i: m["state"] for i, m in mission_marks(e).items()}
                    == {0: "reached", 1: "reached", 2: "reached", 3: "reached", 4: "removed"}
                ),
                3 * REACH_TIMEOUT_S,
            )
            reached = {
                o.target for uav in (74, 112) for o in seen.outcomes_of(uav) if o.phase == "reached"
            }
            assert reached == {0, 1, 2, 3}
            browser.save_screenshot(str(tmp_path / "gui-reached.png"))

            # Abort the team, confirmed: every UAV reports the mission aborted.
            browser.find_element(By.ID, "abort").click()
            assert "Abort mission" in text_of(browser, "confirm-text")
            browser.find_element(By.ID, "confirm-ok").click()
            wait_for(
                browser,
                "both UAVs aborted",
                lambda e: (
                    {i: u["phase"] for i, u in uav_icons(e).items()}
                    == {74: "aborted", 112: "aborted"}
                ),
                30.0,
            )
            assert "abort sent" in text_of(browser, "notice")
        finally:
            sent.subscriber.undeclare()
            seen.close()


#: Whether every target's labels end left of its centre and every UAV's begin right of it.
LABELS_APART = """
const centre = (g) => { const b = g.querySelector('.x, .body').getBoundingClientRect();
                        return b.x + b.width / 2; };
const side = (selector, ok) => [...document.querySelectorAll(selector)].every((g) =>
  [...g.querySelectorAll('text')].every((t) => ok(t.getBoundingClientRect(), centre(g))));
return side('#map [data-target]', (r, c) => r.right <= c)
    && side('#map g.uav', (r, c) => r.left >= c);
"""

#: A press as a person makes it: the button held this long while snapshots keep coming.
PRESS_S = 0.3


def press(driver: Any, selector: str) -> None:
    """A real press of the element `selector` names: pointer down, held, up."""
    element = driver.find_element(By.CSS_SELECTOR, selector)
    ActionChains(driver).move_to_element(element).click_and_hold().pause(
        PRESS_S
    ).release().perform()


def uav_row(driver: Any, uav: int) -> dict[str, Any]:
    return dict(
        driver.execute_script(
            "const r = document.querySelector(`#uav-list tr[data-uav='${arguments[0]}']`);"
            "return {team: r.classList.contains('in-team'), module: r.dataset.module,"
            " opm: r.querySelector('[data-opm]').textContent};",
            uav,
        )
    )


def test_every_press_takes_effect_the_first_time_while_telemetry_flows(
    fleet_with_gui: tuple[str, str], browser: Any, tmp_path: Path
) -> None:
    url, router = fleet_with_gui
    browser.get(url)
    wait_for(browser, "both UAVs", lambda e: set(uav_icons(e)) == {74, 112}, 30.0)
    # Team: each press takes UAV 112 out of the team or puts it back, at once (the page's
    # own state: no round trip to wait for).
    for expected in (False, True, False, True):
        press(browser, "#uav-list tr[data-uav='112'] td:nth-child(4)")
        assert uav_row(browser, 112)["team"] is expected
    # OPM: one press turns UAV 74's module off, as its own state then says; one back on.
    for module in ("off", "on"):
        press(browser, "#uav-list tr[data-uav='74'] [data-opm]")
        wait_until(lambda m=module: uav_row(browser, 74)["module"] == m, 15.0, f"module {module}")
    # A target's delete button, on the third of three targets.
    zoom_out(browser)
    for lat in (35.70, 35.71, 35.72):
        click_at(browser, lat, -120.78)
    wait_for(browser, "3 targets", lambda e: len(target_marks(e)) == 3, 10.0)
    # Labels never collide where a UAV sits on its target: a target's lie left of its X,
    # a UAV's right of its icon.
    assert browser.execute_script(LABELS_APART)
    press(browser, "#target-list [data-delete='2']")
    assert len(target_marks(browser.execute_script(READ_MAP))) == 2
    # A target's latitude typed in the list moves it on the map.
    field = browser.find_element(
        By.CSS_SELECTOR, "#target-list tr[data-target-row='0'] input[data-field='lat']"
    )
    field.send_keys(Keys.CONTROL, "a")
    field.send_keys("35.705")
    browser.find_element(By.ID, "alt").click()  # leaving the field applies it too
    wait_until(
        lambda: float(target_marks(browser.execute_script(READ_MAP))[0]["lat"]) == 35.705,
        5.0,
        "target 0 at the typed latitude",
    )
    # Load asks before it replaces targets on the map; a file over the upload limit is
    # refused with a message, not silently.
    drop_file(browser, "big.bin", b"\x00" * (MAX_UPLOAD + 24))
    assert "Replace the 2 target(s) on the map with big.bin's?" in text_of(browser, "confirm-text")
    browser.find_element(By.ID, "confirm-ok").click()
    wait_until(lambda: "413" in text_of(browser, "load-error"), 10.0, "the upload limit's refusal")
    assert len(target_marks(browser.execute_script(READ_MAP))) == 2  # nothing lost
    # A mission sent from elsewhere while the page holds drafts is drawn beside them.
    other = tmp_path / "other.bin"
    write_targets(other, [Target(35.74, -120.80, 600.0)])
    sent = ground_cli("send-targets", str(other), connect=router, timeout=60)
    assert sent.returncode == 0, sent.stderr
    wait_until(
        lambda: (
            browser.execute_script(
                "return document.querySelectorAll('#map [data-mission-target]').length"
            )
            == 1
        ),
        30.0,
        "the other ground's mission on the map",
    )
    assert len(target_marks(browser.execute_script(READ_MAP))) == 2  # the drafts are kept
    # Send with the ground proposing a plan: offered for min-sum and min-max only.
    assert browser.find_element(By.ID, "propose").get_attribute("disabled") is not None
    proposers = browser.find_element(By.ID, "proposers")
    assert proposers.get_attribute("disabled") is not None
    Select(browser.find_element(By.ID, "objective")).select_by_value("min-sum")
    # UAV proposers (`send-targets --proposers`) are team UAVs' Piccolo IDs: a bad one
    # is said, and nothing is sent (no confirmation asked).
    for typed, said in (("7x", "is not a Piccolo ID"), ("999", "UAV proposer 999 is not in")):
        proposers.clear()
        proposers.send_keys(typed)
        browser.find_element(By.ID, "send").click()
        wait_until(lambda said=said: said in text_of(browser, "notice"), 10.0, f"refusing {typed}")
        assert not browser.execute_script(CONFIRM_OPEN)
    proposers.clear()
    browser.find_element(By.ID, "propose").click()
    browser.find_element(By.ID, "send").click()
    assert "the ground proposing a plan" in text_of(browser, "confirm-text")
    browser.find_element(By.ID, "confirm-ok").click()
    wait_until(lambda: not browser.execute_script(CONFIRM_OPEN), 15.0, "Send's confirmation closed")
    # Per-UAV abort: once a mission is in flight, one press asks to confirm.
    wait_until(
        lambda: browser.execute_script(
            "const b = document.querySelector(\"#uav-list tr[data-uav='112'] [data-abort]\");"
            "return b && getComputedStyle(b).visibility === 'visible';"
        ),
        30.0,
        "the per-UAV abort button",
    )
    # Every per-UAV button lies within the panel: nothing overflows it.
    assert browser.execute_script(
        "const panel = document.querySelector('aside');"
        "const edge = panel.getBoundingClientRect().right;"
        "return [...document.querySelectorAll('#uav-list button, #target-list button')]"
        "  .every((b) => b.getBoundingClientRect().right <= edge);"
    )
    press_until_confirmation(browser, "#uav-list tr[data-uav='112'] [data-abort]")
    assert "for UAV 112 alone" in text_of(browser, "confirm-text")
    browser.find_element(By.ID, "confirm-cancel").click()
    # The proposal, and whether the team adopted it, as the UAVs' digests say: the
    # digest shown is the one both UAVs agreed on.
    wait_until(
        lambda: browser.execute_script(PROPOSAL_VERDICT) in ("adopted", "baseline"),
        60.0,
        "the proposal's verdict",
    )
    wait_until(lambda: "agreed" in text_of(browser, "agreement"), 30.0, "the agreement")
    shown = text_of(browser, "proposal")
    assert "proposed by the ground" in shown and "s of CPU" in shown
    agreed = re.search(r"digest ([0-9a-f]{12})", text_of(browser, "agreement"))
    assert agreed is not None and f"digest {agreed[1]}" in shown, shown
    # Its score, by the UAVs' own checks run on the page, and the plan both committed
    # to with its score (from the arrivals they reported).
    assert "last arrival" in shown, shown
    committed = browser.execute_script(COMMITTED_PLANS)
    assert len(committed) == 1 and f"digest {agreed[1]}" in committed[0], committed
    assert "committed by 74, 112" in committed[0] and "last arrival" in committed[0], committed


class CommandsSeen:
    """Every mission and abort put on the bus, to count what each press did."""

    def __init__(self, session: zenoh.Session) -> None:
        self.lock = threading.Lock()
        self.missions: list[MissionTargets] = []
        self.aborts: list[MissionAbort] = []
        self.subscribers = [
            session.declare_subscriber(SPACE.all_mission_targets, self.on_targets),
            session.declare_subscriber(SPACE.all_mission_aborts, self.on_abort),
        ]

    def on_targets(self, sample: zenoh.Sample) -> None:
        message = msgspec.json.decode(sample.payload.to_bytes(), type=MissionTargets)
        with self.lock:
            self.missions.append(message)

    def on_abort(self, sample: zenoh.Sample) -> None:
        message = msgspec.json.decode(sample.payload.to_bytes(), type=MissionAbort)
        with self.lock:
            self.aborts.append(message)

    def close(self) -> None:
        for subscriber in self.subscribers:
            subscriber.undeclare()


@contextlib.contextmanager
def busy_cores(count: int) -> Iterator[list[subprocess.Popen[bytes]]]:
    """`count` processes spinning on the CPU, as a loaded box has; killed on the way out."""
    spinners = [subprocess.Popen([sys.executable, "-c", "while True: pass"]) for _ in range(count)]
    try:
        yield spinners
    finally:
        for spinner in spinners:
            spinner.kill()
            spinner.wait()


def command_states(driver: Any) -> list[dict[str, str]]:
    """The Commands list: each command's kind and state (pending, done, failed), newest first."""
    states: list[dict[str, str]] = driver.execute_script(
        "return [...document.querySelectorAll('#command-list li')].map((li) =>"
        " ({cmd: li.dataset.cmd, state: li.dataset.commandState, text: li.innerText}));"
    )
    return states


CONFIRM_OPEN = "return !document.querySelector('#confirm').hidden;"


def press_until_confirmation(driver: Any, selector: str) -> None:
    """Press `selector` until its confirmation opens.

    A press on a loaded box can land while the page re-lays itself out under the pointer
    (a render between the pointer's move and its press): then no confirmation opens, and
    the operator presses again. So does this, a bounded number of times."""
    for _ in range(3):
        press(driver, selector)
        try:
            wait_until(lambda: driver.execute_script(CONFIRM_OPEN), 15.0, "the confirmation")
            return
        except AssertionError:
            continue
    raise AssertionError(f"three presses of {selector} opened no confirmation")


def press_and_drop(driver: Any, selector: str) -> None:
    """Press `selector`, confirm, and drop the page's socket at once, as a loaded box
    does: the command is on its way or done, its reply lost with the socket."""
    press_until_confirmation(driver, selector)
    driver.execute_script(
        "document.querySelector('#confirm-ok').click(); window.fleetPage.dropConnection();"
    )


def wait_command_answered(driver: Any, cmd: str, timeout: float) -> dict[str, str]:
    found: list[dict[str, str]] = []

    def answered() -> bool:
        found[:] = [c for c in command_states(driver) if c["cmd"] == cmd]
        return bool(found) and found[0]["state"] != "pending"

    wait_until(answered, timeout, f"the {cmd} command answered (list: {found})")
    return found[0]


ABORT_112_SHOWN = """
const b = document.querySelector("#uav-list tr[data-uav='112'] [data-abort]");
return b && getComputedStyle(b).visibility === 'visible';
"""


def test_under_cpu_stress_send_and_abort_take_effect_once_though_the_socket_drops(
    fleet_with_gui: tuple[str, str], browser: Any
) -> None:
    """Two spinning processes on a 2-core box; the socket drops right after each press.
    The page shows each command pending, then done; Send made one mission and the
    per-UAV Abort one abort (the page re-sent each after reconnecting: the ground
    answered the repeat without doing it again), and only that UAV stopped."""
    url, router = fleet_with_gui
    targets_file = files("fleet") / "scenarios" / "head_on_targets.bin"
    with client_session(router) as session, busy_cores(2):
        seen = CommandsSeen(session)
        try:
            browser.get(url)
            wait_for(browser, "both UAVs", lambda e: set(uav_icons(e)) == {74, 112}, 60.0)
            drop_file(browser, "head_on_targets.bin", targets_file.read_bytes())
            wait_for(browser, "3 drafts", lambda e: len(target_marks(e)) == 3, 30.0)

            press_and_drop(browser, "#send")
            send = wait_command_answered(browser, "send", 90.0)
            assert send["state"] == "done", send
            assert browser.execute_script("return window.fleetPage.reconnects()") >= 1
            elements = wait_for(
                browser, "the mission's targets", lambda e: len(mission_marks(e)) == 3, 60.0
            )
            assert not target_marks(elements)  # sent: no longer drafts

            wait_until(
                lambda: browser.execute_script(ABORT_112_SHOWN), 60.0, "the per-UAV abort button"
            )
            press_and_drop(browser, "#uav-list tr[data-uav='112'] [data-abort]")
            abort = wait_command_answered(browser, "abort", 90.0)
            assert abort["state"] == "done", abort
            wait_for(
                browser,
                "UAV 112 aborted",
                lambda e: uav_icons(e).get(112, {}).get("phase") == "aborted",
                60.0,
            )
            assert uav_icons(browser.execute_script(READ_MAP))[74]["phase"] != "aborted"
            with seen.lock:
                missions = list(seen.missions)
                aborts = list(seen.aborts)
            assert [m.team for m in missions] == [(74, 112)]
            assert [(a.mission, a.uav) for a in aborts] == [(missions[0].mission, 112)]
            # Each command once in the list, answered.
            assert [c["cmd"] for c in command_states(browser)] == ["abort", "send"]
        finally:
            seen.close()
