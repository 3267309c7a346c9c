"""The fleet view: ten robots at a glance, the one that waits for an operator first, and acted on from there.

A real ``caretaker serve`` with ten robots (ten bindings of the IVA robot side, each its own robot,
on the simulated systems) and Chromium. Nine runs keep watch (a long wait: running, nobody needed);
the seventh robot's run holds at a manual instruction. Whatever order the runs started in and the
robots' names, the holding one is listed first; its row opens its run, Done there lets it go on,
and the fleet then lists it with the others. The order itself (host lost, link silent, limits out):
test_fleet_entries.py.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import yaml
from playwright.sync_api import Page, expect

from support.operator_page import expect_current, instruction
from support.procedures import REPO
from support.web_server import WebServer, start_server

pytestmark = pytest.mark.slow(seconds=20)

ROBOTS = [f"hab{n:02d}" for n in range(1, 11)]
HOLDING = "hab07"
WATCH = """<?xml version="1.0" encoding="UTF-8"?>
<procedure id="fleet_watch" title="Keep watch over the CDRA" version="1">
  <uses system="cdra"/>
  <step title="Watch">
    <wait seconds="900"/>
  </step>
</procedure>
"""
LOOK = """<?xml version="1.0" encoding="UTF-8"?>
<procedure id="fleet_look" title="Look at the CDRA cabinet" version="1">
  <uses system="cdra"/>
  <step title="Look">
    <manual>Look at the CDRA cabinet and mark this done when it is closed.</manual>
    <wait seconds="900"/>
  </step>
</procedure>
"""


def _bindings(folder: Path) -> Path:
    """Ten robots: the shipped IVA binding, each under its own robot name."""
    shipped = REPO / "sysrep" / "bindings" / "iva.yaml"
    folder.mkdir()
    for robot in ROBOTS:
        data = yaml.safe_load(shipped.read_text(encoding="utf-8"))
        data["robot"] = robot
        for system in data["systems"]:
            system["sysrep"] = str((shipped.parent / system["sysrep"]).resolve())
        (folder / f"{robot}.yaml").write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return folder


@pytest.fixture(scope="module")
def fleet_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[WebServer]:
    tmp = tmp_path_factory.mktemp("fleet")
    shelf = tmp / "procedures"
    shelf.mkdir()
    (shelf / "fleet_watch.xml").write_text(WATCH, encoding="utf-8")
    (shelf / "fleet_look.xml").write_text(LOOK, encoding="utf-8")
    served = start_server(tmp, shelf, options=["--bindings", str(_bindings(tmp / "bindings"))])
    yield served
    served.process.stop()


def _start(page: Page, url: str, robot: str) -> str:
    procedure = "fleet_look.xml" if robot == HOLDING else "fleet_watch.xml"
    body = {"procedure": procedure, "binding": f"{robot}.yaml", "mode": "autonomous", "rehearsal": True}
    started = page.request.post(f"{url}/api/runs", data=body, headers={"X-CSRF-Token": page.evaluate("view.me.csrf")})
    assert started.status == 201, started.text()
    return str(started.json()["run_id"])


def test_the_robot_that_waits_for_an_operator_is_listed_first_and_acted_on_from_the_fleet(
    open_page: Callable[[WebServer, str], Page], fleet_server: WebServer
) -> None:
    alice = open_page(fleet_server, "alice")
    fleet = alice.locator("#fleet-list > li")
    expect(fleet).to_have_count(len(ROBOTS))  # every robot, idle
    expect(alice.locator("#fleet-summary")).to_have_text("10 robots")
    runs = {robot: _start(alice, fleet_server.url, robot) for robot in ROBOTS}

    expect(fleet.first).to_have_attribute("data-robot", HOLDING)
    expect(fleet.first.locator(".fleet-state")).to_have_text("holds for an operator")
    expect(fleet.first.locator(".fleet-needs")).to_contain_text("waits for: ")
    expect(alice.locator("#fleet-summary")).to_have_text("10 robots · 1 wait for an operator")
    expect(alice.locator('#fleet-list > li[data-urgency="4"]')).to_have_count(len(ROBOTS) - 1)
    expect(alice.locator("#fleet-list > li .fleet-state").nth(1)).to_have_text("running")
    assert fleet.first.locator("a").inner_text() == runs[HOLDING]

    fleet.first.locator("a").click()  # the fleet's row opens its run; the operator acts there
    expect(alice.locator("#run-id")).to_have_text(runs[HOLDING])
    expect_current(instruction(alice, "1.1"))
    instruction(alice, "1.1").locator("button.done").click()
    expect_current(instruction(alice, "1.2"))

    holding = alice.locator(f'#fleet-list > li[data-robot="{HOLDING}"]')
    expect(holding).to_have_attribute("data-urgency", "4")
    expect(holding.locator(".fleet-needs")).to_have_count(0)
    expect(alice.locator("#fleet-summary")).to_have_text("10 robots")
    expect(holding).to_have_class(re.compile(r"\bopen\b"))  # the run open on this page
