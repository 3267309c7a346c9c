"""The fleet view of ten habitats: the one that waits for an operator first, and acted on from there.

Ten emulated habitats (support/emulated_habitat.py: a real bridge, link and onboard executive each,
the simulated IVA robot), one ``caretaker supervise`` of all ten, and a console that hands its
onboard starts to the supervisors (``caretaker serve --via-supervisor``), all on one PostgreSQL
ground database, and Chromium. The operator starts every run from the console, "run on the
habitat": each goes to the supervisor, which uplinks it and hosts it for the consoles. Nine keep
watch (a long wait: running, nobody needed); the seventh holds at a manual instruction for an
operator at the consoles. Whatever the order of the starts and the robots' names, the holding one
is listed first; its row opens its run, Done there reaches the habitat through the supervisor, and
the fleet then lists it running with the others. The order in full (host lost, link silent,
limits out): test_fleet_entries.py.
"""

from __future__ import annotations

import re
from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, expect

from support.browser import signed_in_pages
from support.emulated_habitat import EmulatedHabitat, fleet, supervise
from support.operator_page import expect_current, instruction, sign_in_on
from support.postgres import PostgresServer
from support.web_server import WebServer, new_ground_database, start_server

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=300), pytest.mark.timeout(1800)]

HABITATS = 10
HOLDING = "iva-hab07"
DELAY = 0.2  # s one way: the view is the subject, not the light time
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


@pytest.fixture(scope="module")
def ground(
    postgres: PostgresServer, ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[WebServer, list[EmulatedHabitat], str]]:
    """The ten habitats, their supervisor (and the name it hosts runs as), and a console whose bindings
    are the habitats'."""
    tmp = tmp_path_factory.mktemp("fleet")
    database = new_ground_database("postgresql", tmp, postgres)
    shelf, bindings = tmp / "procedures", tmp / "bindings"
    shelf.mkdir()
    bindings.mkdir()
    (shelf / "fleet_watch.xml").write_text(WATCH, encoding="utf-8")
    (shelf / "fleet_look.xml").write_text(LOOK, encoding="utf-8")
    with fleet(tmp / "habitats", ros_env, [DELAY] * HABITATS) as habitats:
        supervisor, supervisor_name = supervise(database.url, habitats, ros_env, "supervise")
        try:
            for habitat in habitats:
                (bindings / habitat.binding.name).symlink_to(habitat.binding)
            deployments = [f"--deployments={h.binding.parent / f'{h.name}-habitat.yaml'}" for h in habitats]
            console = start_server(
                tmp,
                shelf,
                database=database,
                options=["--via-supervisor", "--bindings", str(bindings), *deployments],
                env=ros_env,
            )
            try:
                yield console, habitats, supervisor_name
            finally:
                console.process.stop()
        finally:
            supervisor.stop()


def _start_on_the_habitat(page: Page, url: str, robot: str) -> None:
    """The operator starts ``robot``'s run on its habitat. A crowded machine may keep the habitat's
    answer past the console's wait: the start then says its runner goes on (502, ``ended`` false),
    and the run shows in the fleet once the habitat took it, as an operator would see it."""
    procedure = "fleet_look.xml" if robot == HOLDING else "fleet_watch.xml"
    body = {"procedure": procedure, "binding": f"{robot}.yaml", "mode": "autonomous", "onboard": True}
    body["rehearsal"] = True  # drafts, on emulated robots that say they are simulators
    started = page.request.post(
        f"{url}/api/runs", data=body, headers={"X-CSRF-Token": page.evaluate("view.me.csrf")}, timeout=120_000
    )
    going_on = started.status == 502 and started.json().get("ended") is False
    assert started.status == 201 or going_on, started.text()


def test_the_habitat_that_waits_for_an_operator_is_listed_first_and_acted_on_from_the_fleet(
    browser: Browser, ground: tuple[WebServer, list[EmulatedHabitat], str]
) -> None:
    console, habitats, supervisor = ground
    robots = [h.name for h in habitats]
    with signed_in_pages(browser, sign_in_on) as open_as:
        alice = open_as(console.url, "alice")
        fleet_rows = alice.locator("#fleet-list > li")
        expect(fleet_rows).to_have_count(HABITATS)  # every habitat's robot, idle
        expect(alice.locator("#fleet-summary")).to_have_text(f"{HABITATS} robots")
        for robot in robots:
            _start_on_the_habitat(alice, console.url, robot)

        first = fleet_rows.first
        expect(first).to_have_attribute("data-robot", HOLDING)
        expect(first.locator(".fleet-state")).to_have_text("holds for an operator")
        expect(first.locator(".fleet-needs")).to_contain_text("waits for: ")
        expect(first.locator(".meta").first).to_contain_text(f"onboard · {supervisor}")  # hosted by the supervisor
        expect(alice.locator("#fleet-summary")).to_have_text(f"{HABITATS} robots · 1 wait for an operator")
        expect(alice.locator('#fleet-list > li[data-urgency="4"]')).to_have_count(HABITATS - 1)
        run_id = first.locator("a").inner_text()

        first.locator("a").click()  # the fleet's row opens its run; the operator acts there
        expect(alice.locator("#run-id")).to_have_text(run_id)
        expect_current(instruction(alice, "1.1"))
        instruction(alice, "1.1").locator("button.done").click()  # forwarded to the supervisor, sent up
        expect_current(instruction(alice, "1.2"))

        holding = alice.locator(f'#fleet-list > li[data-robot="{HOLDING}"]')
        expect(holding).to_have_attribute("data-urgency", "4")
        expect(holding.locator(".fleet-needs")).to_have_count(0)
        expect(alice.locator("#fleet-summary")).to_have_text(f"{HABITATS} robots")
        expect(holding).to_have_class(re.compile(r"\bopen\b"))  # the run open on this page
    [habitat] = [h for h in habitats if h.name == HOLDING]
    done = [e for e in habitat.onboard_chain(run_id) if e.kind == "instruction_completed"]
    assert [(e.instruction, e.actor) for e in done] == [("1.1", "alice")]  # on the habitat's own record
