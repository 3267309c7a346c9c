"""Two consoles on one ground database share their runs through it, and only through it.

Two ``caretaker serve`` processes on one database — a SQLite file, then PostgreSQL as the
locked-down runner role — with the simulated systems behind them: a run started on console A
is live on console B (runs list and run page), an operator on B acts on it (forwarded through
the database to A, which performs it as that operator), an observer on B is refused, a password
change ends that user's sessions on both consoles, and when A dies B shows the run interrupted
(A's lease ran out) and resumes it. The consoles never talk to each other: each knows only the
database URL.
"""

from __future__ import annotations

import re
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Locator, Page, expect

from console.terminal_host import HostedElsewhere, TerminalHost
from pride.executive import Executive, Mode
from procedure_language.lint import check_procedure
from procedure_language.sysrep import load_sysrep_dir
from records.audit_log import AuditLog
from support.operator_page import audit_row, expect_ended, instruction, start_run
from support.processes import COMMAND_HANG_S
from support.simulated_systems import open_simulated_systems
from support.web_server import PEOPLE, REPO, WebServer, new_ground_database, procedure_shelf, start_server

WALKTHROUGH = "web_walkthrough.xml"
#: Short, so that a dead console's runs show interrupted soon (the default is 10 s).
LEASE = "3"


@pytest.fixture(params=["sqlite", "postgresql"])
def consoles(request: pytest.FixtureRequest, tmp_path: Path) -> Iterator[tuple[WebServer, WebServer]]:
    postgres = request.getfixturevalue("postgres") if request.param == "postgresql" else None
    database = new_ground_database(request.param, tmp_path, postgres)
    shelf = procedure_shelf(tmp_path)
    started: list[WebServer] = []
    try:
        for name in ("console A", "console B"):
            started.append(
                start_server(tmp_path, shelf, database=database, options=["--lease", LEASE, "--console", name])
            )
        yield started[0], started[1]
    finally:
        for served in started:
            served.process.stop()


def run_line(page: Page, run_id: str) -> Locator:
    return page.locator(f'#run-list li[data-run-id="{run_id}"]')


def test_a_run_started_on_one_console_is_live_on_the_other_and_acted_on_from_there(
    consoles: tuple[WebServer, WebServer], open_page: Callable[[WebServer, str], Page]
) -> None:
    first, second = consoles
    alice = open_page(first, "alice")
    bob = open_page(second, "bob")
    run_id = start_run(alice, WALKTHROUGH, "manual")
    expect(alice.locator("#run-host")).to_have_text("hosted by this console")

    # B's runs list is pushed the new run; its page follows it live, hosted by A
    expect(run_line(bob, run_id)).to_have_attribute("data-status", "active")
    expect(run_line(bob, run_id).locator(".meta")).to_contain_text("on console A")
    run_line(bob, run_id).locator('a[href^="#run="]').click()
    expect(bob.locator("#connection")).to_have_attribute("data-state", "open")
    expect(bob.locator("#run-host")).to_have_text("hosted by console A")

    # bob acts on B; A performs it as bob, and both pages show it
    instruction(bob, "1.1").locator("button.perform").click()
    for page in (alice, bob):
        expect(instruction(page, "1.1").locator(".mark")).to_contain_text("completed by bob")
        expect(audit_row(page, "command_sent", "1.1", "bob")).to_have_count(1)
    # and alice's action on A shows on B
    instruction(alice, "2.1").locator(".line > .breakpoint").click()
    expect(instruction(bob, "2.1")).to_have_class(re.compile(r"\bhas-breakpoint\b"))
    expect(bob.locator("#watchers")).to_contain_text("alice")

    # an observer on B is refused there, whatever the page shows
    carol = open_page(second, "carol")
    carol.goto(f"{second.url}/#run={run_id}")
    expect(carol.locator("#connection")).to_have_attribute("data-state", "open")
    status = carol.evaluate(
        """async (runId) => (await fetch(`/api/runs/${runId}/actions`, {method: "POST",
        headers: {"Content-Type": "application/json", "X-CSRF-Token": view.me.csrf},
        body: JSON.stringify({action: "perform", instruction: "2.1"})})).status""",
        run_id,
    )
    assert status == 403

    # a password changed at the database ends bob's sessions on every console
    bob_on_first = open_page(first, "bob")
    bob_on_first.goto(f"{first.url}/#run={run_id}")
    expect(bob_on_first.locator("#connection")).to_have_attribute("data-state", "open")
    changed = subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "accounts", "--db", first.database.owner_url, "set-password", "bob"],
        input=PEOPLE["bob"][2] + "-new\n",
        capture_output=True,
        text=True,
        timeout=COMMAND_HANG_S,
    )
    assert changed.returncode == 0, changed.stderr
    for page in (bob, bob_on_first):
        expect(page.locator("#sign-in-view")).to_be_visible()
        expect(page.locator("#sign-in-error")).to_contain_text("password changed")


def test_when_the_hosting_console_dies_the_other_shows_the_run_interrupted_and_resumes_it(
    consoles: tuple[WebServer, WebServer], open_page: Callable[[WebServer, str], Page]
) -> None:
    first, second = consoles
    alice = open_page(first, "alice")
    run_id = start_run(alice, WALKTHROUGH, "manual")
    bob = open_page(second, "bob")
    bob.goto(f"{second.url}/#run={run_id}")
    expect(bob.locator("#run-host")).to_have_text("hosted by console A")

    first.process.kill()  # kill -9: no stop recorded, no host row released; only the lease runs out
    expect(bob.locator("#run-status")).to_have_text("interrupted")
    expect(bob.locator("#hold")).to_contain_text("console A, which ran it, went silent")
    expect(run_line(bob, run_id)).to_have_attribute("data-status", "interrupted")
    expect(run_line(bob, run_id).locator(".meta")).to_contain_text("console A went silent")

    bob.click("#resume")
    expect(bob.locator("#resume-warning")).to_contain_text("console A, which ran it, stopped renewing its claim")
    bob.select_option("#resume-binding", "iva.yaml")
    bob.click("#resume-yes")
    expect(bob.locator("#run-host")).to_have_text("hosted by this console")
    instruction(bob, "1.1").locator("button.perform").click()
    expect(instruction(bob, "1.1").locator(".mark")).to_contain_text("completed by bob")
    bob.click("#stop")
    bob.fill("#stop-reason", "taken over after console A died")
    bob.click("#stop-yes")
    expect_ended(bob, "stopped")
    expect(bob.locator('#audit li[data-kind="run_resumed"][data-actor="bob"]')).to_have_count(1)


def test_a_run_driven_outside_a_console_is_live_on_the_consoles_and_acted_on_from_them(
    consoles: tuple[WebServer, WebServer],
    open_page: Callable[[WebServer, str], Page],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """What `caretaker run` does with a TerminalHost: this test process is the runner."""
    first, _ = consoles
    monkeypatch.setenv("SIMULATED_CAMERA_DIR", str(tmp_path))
    audit = AuditLog(first.database.url)
    gateway = open_simulated_systems(str(REPO / "sysrep" / "bindings" / "iva.yaml"))
    host = TerminalHost(audit, binding="iva.yaml", name="runner at the bench")
    try:
        checked = check_procedure(first.procedures / WALKTHROUGH, load_sysrep_dir(REPO / "sysrep"))
        executive = Executive(checked, gateway, audit, run_id="walkthrough-at-the-terminal", mode=Mode.MANUAL)
        host.host(executive, gateway, checked, started_by="dave")
        executive.start("dave")

        bob = open_page(first, "bob")
        bob.goto(f"{first.url}/#run={executive.run_id}")
        expect(bob.locator("#run-host")).to_have_text("hosted by runner at the bench")
        instruction(bob, "1.1").locator("button.perform").click()  # forwarded to this process's executive
        expect(instruction(bob, "1.1").locator(".mark")).to_contain_text("completed by bob")
        assert executive.snapshot().statuses["1.1"].value == "completed"
        other = TerminalHost(audit, binding="iva.yaml")
        try:
            with pytest.raises(HostedElsewhere, match="runner at the bench"):  # nobody else may resume it meanwhile
                other.check_free(executive.run_id)
        finally:
            other.close()
        executive.stop("dave", "done at the bench")
        expect_ended(bob, "stopped")
    finally:
        host.close()
        gateway.close()
        audit.close()
