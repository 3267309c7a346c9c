"""Issue 19's ground segment: two consoles, two robots, one PostgreSQL database, real browsers.

Two ``caretaker up`` stacks side by side — the IVA robot in this session's ROS domain, the EVA
arm in another, each with its own rosbridge port — and two ``caretaker serve`` processes on one
PostgreSQL database (as the locked-down runner role), each given the rosbridge URL of each
robot's binding and nothing about the other console. Console A runs the CDRA filter replacement
and the EVA inspection at once, autonomously; operators on both consoles answer the holds
through the page: an action taken in one console shows in the other (forwarded to the run's
host, console A, through the database), the IVA unlock sent for approval on A and approved on B.
Both runs complete; each run's log, telemetry and
camera stay its own; a second run on a robot already controlled is refused.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import ExitStack
from dataclasses import dataclass

import pytest
from playwright.sync_api import Browser, Locator, Page, expect

from ground.action_requests import ANSWER_WITHIN_S, TAKE_WITHIN_S
from records.audit_log import AuditLog
from support.browser import signed_in_pages
from support.operator_page import (
    IVA,
    UNLOCK,
    audit_row,
    expect_current,
    expect_ended,
    instruction,
    send_for_approval,
    shown_image_width,
    sign_in_on,
    start_run,
    stop_run,
    where_the_run_is,
)
from support.postgres import PostgresServer
from support.processes import ManagedProcess, caretaker
from support.ros_domain import claim_ros_domain
from support.web_server import REPO, WebServer, new_ground_database, start_server

#: Two robots' procedures run at once: the inner waits below (MOTION_MS each) must be what fails
#: first, with what the page and the processes show, not the suite's 300 s per test.
pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=180), pytest.mark.timeout(1500)]

EVA = "eva_inspection.xml"
#: An arm's motions at full simulation speed still take minutes on two loaded cores.
MOTION_MS = 240_000
#: The longest a forwarded action may take by the protocol, and the other page's refresh on loaded cores.
FORWARDED_MS = int((TAKE_WITHIN_S + ANSWER_WITHIN_S) * 1000) + 30_000
#: A start's answer: one that would be allowed opens the robot's gateway (JVM and rosbridge work) first.
START_MS = 120_000


@dataclass
class Ground:
    first: WebServer  # console A: hosts both runs
    second: WebServer  # console B: follows them through the database
    robots: dict[str, ManagedProcess]  # each robot's ``caretaker up``

    def current(self, page: Page, number: str) -> Locator:
        """The instruction, once it is the one the run holds at (PAX may take minutes of motion to get there)."""
        found = instruction(page, number)
        try:
            expect_current(found, timeout=MOTION_MS)
        except AssertionError as failure:
            raise self.failure(page, f"instruction {number} did not become current", failure) from None
        return found

    def seen_by_the_other(self, acting: Page, row: Locator, text: str) -> None:
        """An operator's record, shown in the other console's audit log; else what the acting page said.

        A record made on B is forwarded to its host A, which has TAKE_WITHIN_S to take it and
        ANSWER_WITHIN_S to answer before B calls it not performed or unknown; the page then says so.
        """
        try:
            expect(row).to_contain_text(text, timeout=FORWARDED_MS)
        except AssertionError as failure:
            said = acting.locator("#action-error").inner_text()
            raise self.failure(
                acting, f"the other console did not show {text!r}; the acting page said {said!r}", failure
            ) from None

    def ended_in(self, page: Page, status: str) -> None:
        try:
            expect(page.locator("#run-status")).to_have_text(status, timeout=MOTION_MS)
        except AssertionError as failure:
            raise self.failure(page, f"the run did not end {status}", failure) from None
        expect_ended(page, status)

    def failure(self, page: Page, what: str, failure: AssertionError) -> AssertionError:
        """``what`` went wrong, with what ``page`` shows of its run and what each process printed last."""
        logs = {
            "console A": self.first.process,
            "console B": self.second.process,
            **{f"robot {name}": up for name, up in self.robots.items()},
        }
        printed = "\n".join(f"--- {name} printed last:\n{process.tail(80)}" for name, process in logs.items())
        return AssertionError(f"{what}\n{failure}\n--- the page shows:\n{where_the_run_is(page)}\n{printed}")


@pytest.fixture(scope="module")
def ground(
    tmp_path_factory: pytest.TempPathFactory, postgres: PostgresServer, ros_env: dict[str, str]
) -> Iterator[Ground]:
    tmp = tmp_path_factory.mktemp("ground")
    database = new_ground_database("postgresql", tmp, postgres)
    robots = {"iva": ros_env, "eva": {**ros_env, "ROS_DOMAIN_ID": str(claim_ros_domain())}}  # one domain per robot
    with ExitStack() as stack:
        ups = {}
        for name, env in robots.items():  # both come up at once
            ups[name] = caretaker(
                "up", name, "--time-scale", "0", "--bridge-port", "0", "--verbose", env=env, name=f"up-{name}"
            )  # --verbose: each part's log, for a failure's message
            stack.callback(ups[name].stop)
        urls = [f"{name}.yaml={up.wait_for_line(r'^READY stack ', 240).split()[-1]}" for name, up in ups.items()]
        consoles = []
        for name in ("console A", "console B"):
            console = start_server(
                tmp,
                REPO / "procedures",
                database=database,
                rosbridge=urls,
                cameras=["eva.yaml=ee_camera"],
                options=["--console", name],
            )
            stack.callback(console.process.stop)
            consoles.append(console)
        yield Ground(consoles[0], consoles[1], ups)


@pytest.fixture
def open_page(browser: Browser) -> Iterator[Callable[[WebServer, str], Page]]:
    with signed_in_pages(browser, sign_in_on) as open_as:
        yield lambda on, user: open_as(on.url, user)


def follow(page: Page, console: WebServer, run_id: str) -> Page:
    page.goto(f"{console.url}/#run={run_id}")
    expect(page.locator("#connection")).to_have_attribute("data-state", "open")
    return page


def test_one_console_runs_both_robots_and_both_consoles_act_on_both_runs(
    ground: Ground, open_page: Callable[[WebServer, str], Page]
) -> None:
    first, second = ground.first, ground.second
    alice_iva, alice_eva = open_page(first, "alice"), open_page(first, "alice")
    iva_run = start_run(alice_iva, IVA, "autonomous", binding="iva.yaml")
    eva_run = start_run(alice_eva, EVA, "autonomous", binding="eva.yaml")
    bob_iva = follow(open_page(second, "bob"), second, iva_run)
    bob_eva = follow(open_page(second, "bob"), second, eva_run)

    # each console lists both runs live; console B shows them hosted by A
    for page, here in ((alice_iva, "on this console"), (bob_iva, "on console A")):
        for run_id in (iva_run, eva_run):
            line = page.locator(f'#run-list li[data-run-id="{run_id}"]')
            expect(line).to_have_attribute("data-status", "active")
            expect(line.locator(".meta")).to_contain_text(here)
    expect(bob_eva.locator("#run-host")).to_have_text("hosted by console A")
    # telemetry read by console A's gateway of each robot, shown on B as A publishes it
    for page in (bob_iva, bob_eva):
        telemetry = instruction(page, "1.1").locator(".telemetry")
        expect(telemetry).to_contain_text("Affordance Template Server Active = true")

    # an operator on B pauses the EVA run, one on A continues it: each sees the other's action
    # (B's pause is forwarded to the run's host A: it may take the protocol's whole time to act)
    bob_eva.click("#pause")
    ground.seen_by_the_other(bob_eva, alice_eva.locator('#audit li[data-kind="paused"][data-actor="bob"]'), "paused")
    expect(alice_eva.locator("#continue")).to_be_enabled()
    alice_eva.click("#continue")
    continued = bob_eva.locator('#audit li[data-kind="continued"][data-actor="alice"]')
    ground.seen_by_the_other(alice_eva, continued, "continued")

    # IVA: alice on A sends the hazardous unlock for approval; bob approves it from B, and it is sent
    ground.current(alice_iva, UNLOCK)
    send_for_approval(alice_iva, UNLOCK)
    ground.current(bob_iva, UNLOCK).locator("button.approve").click()
    bob_iva.click("#confirm-yes")
    ground.seen_by_the_other(bob_iva, audit_row(alice_iva, "approval_given", UNLOCK, "bob"), "approved alice's command")
    expect(audit_row(alice_iva, "command_sent", UNLOCK, "PAX")).to_contain_text("sent by alice, approved by bob")

    # IVA: bob confirms the manual instruction from B; the run on A goes on
    ground.current(bob_iva, "2.6").locator("button.done").click()
    expect(instruction(alice_iva, "2.6").locator(".mark")).to_contain_text("completed by bob")

    # EVA: the four targets' assessments, answered alternately from A and from B
    for target, page in zip(("2", "3", "4", "5"), (alice_eva, bob_eva, alice_eva, bob_eva), strict=True):
        assessment = ground.current(page, f"{target}.1/2.2")
        assessment.locator("select.record-value").select_option("false")
        assessment.locator("button.record").click()
        actor = "alice" if page is alice_eva else "bob"
        other = bob_eva if page is alice_eva else alice_eva
        ground.seen_by_the_other(page, audit_row(other, "operator_input", f"{target}.1/2.2", actor), "damage = false")
        if target == "2":  # the image the EVA arm took, from console A's disk, shown on B out of the database
            expect(bob_eva.locator("#camera-caption")).to_contain_text(".png")
            assert shown_image_width(bob_eva.locator("#camera")) > 0

    # IVA: the clean filter's id recorded on A; meanwhile a second run on the IVA robot is refused
    ground.current(alice_iva, "4.1").locator("input.record-value").fill("CDRA-F-0012")
    instruction(alice_iva, "4.1").locator("button.record").click()
    recorded = audit_row(bob_iva, "operator_input", "4.1", "alice")
    ground.seen_by_the_other(alice_iva, recorded, "clean filter id = CDRA-F-0012")
    second_controller = second_run_on_the_same_robot(open_page(second, "bob"))
    ground.current(bob_iva, "5.1").locator("button.done").click()

    for page in (alice_iva, bob_iva):
        ground.ended_in(page, "completed")
    for page in (alice_eva, bob_eva):
        ground.ended_in(page, "completed")

    # each run's record is its own: its robot's systems only, whole chains
    log = AuditLog(first.database.url)
    try:
        for run_id, own, foreign in ((iva_run, "cdra", "camera"), (eva_run, "camera", "cdra")):
            systems = {e.data.to_json().get("system") for e in log.events(run_id) if e.kind.value == "command_sent"}
            assert own in systems and foreign not in systems, (run_id, systems)
            assert log.verify(run_id).ok, log.verify(run_id).describe()
    finally:
        log.close()
    # the IVA page never showed the EVA camera (the consoles watch an EVA camera only)
    expect(alice_iva.locator("#camera")).to_be_hidden()
    assert "controlled by" in second_controller, f"a second run on the IVA robot was not refused: {second_controller!r}"


def second_run_on_the_same_robot(page: Page) -> str:
    """Try to start another IVA run (manual: it sends nothing by itself); the refusal, or what happened."""
    page.select_option("#start-procedure", IVA)
    page.select_option("#start-binding", "iva.yaml")
    page.check("#start-form input[name=mode][value=manual]")
    page.check("#start-rehearsal")  # the shipped procedure is a draft here: a rehearsal on the simulator
    page.click("#start-button")
    page.wait_for_function(
        "() => document.getElementById('start-error').textContent || location.hash.includes('run=')",
        timeout=START_MS,
    )
    refusal = page.locator("#start-error").inner_text()
    if "run=" in page.evaluate("location.hash"):  # it started: stop it before it could do anything
        expect(page.locator("#connection")).to_have_attribute("data-state", "open")
        stop_run(page, "a second controller of the IVA robot must not exist")
        return "started as a second controller"
    return refusal
