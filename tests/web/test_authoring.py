"""The Author page: palette, drag-and-drop, typed forms, live lint, saving XML that runs; releasing
a version; and the commands that need a second operator (issue 29).

The authored procedure runs in the web view against the real robot side (``caretaker up --scene
iva``): the arm really pulls the filter the operator names out of the rack. On the same stack
(one per module: starting one costs seconds of CPU), ``web_critical.xml`` unlocks the real CDRA
latch: a draft runs only as a rehearsal, marked so; a second operator releases it; an edited
release is refused; its hazardous command waits for a second operator, on another console, and
is never sent on the sender's own approval.
"""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from author_page import bind_arg, card, drop, meaning, set_arg, set_attr
from playwright.sync_api import Locator, Page, expect

from console.authoring import check_document, read_document
from pride.events import EventKind
from procedure_language.parser import load_procedure
from procedure_language.sysrep import load_sysrep_dir
from records.audit_log import AuditLog
from support.operator_page import (
    audit_row,
    expect_current,
    expect_ended,
    instruction,
    screenshot,
    start_run,
    stop_run,
)
from support.procedures import FIXTURES
from support.web_server import REPO, WebServer, server_on_real_stack, start_server

SHIPPED = sorted(p.name for p in (REPO / "procedures").glob("*.xml"))
#: The lab bench's procedures with monitors (a SysRep limit, a condition), outputs, sets and call results.
LAB = ["lab_monitors.xml", "lab_outputs.xml", "lab_locate.xml"]
#: The latch: a hazardous command (1.2) between verifies, no arm motion.
CRITICAL = "web_critical.xml"
UNLOCK = "1.2"


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory, ros_env: dict[str, str]) -> Iterator[WebServer]:
    """A web server on the real IVA stack, with a procedure shelf of its own to save into."""
    tmp = tmp_path_factory.mktemp("author")
    shelf = tmp / "procedures"
    shutil.copytree(REPO / "procedures", shelf)
    shutil.copy(REPO / "tests" / "web" / "fixtures" / "procedures" / CRITICAL, shelf)  # edited by a test
    with server_on_real_stack(tmp, shelf, ros_env) as served:
        yield served


@pytest.mark.parametrize(
    ("shelf", "sysreps", "name"),
    [*((REPO / "procedures", REPO / "sysrep", n) for n in SHIPPED), *((FIXTURES, FIXTURES / "sysrep", n) for n in LAB)],
    ids=[*SHIPPED, *LAB],
)
def test_opening_and_saving_a_procedure_changes_nothing(shelf: Path, sysreps: Path, name: str, tmp_path: Path) -> None:
    source = shelf / name
    for sibling in shelf.glob("*.xml"):  # calls resolve next to the saved file
        (tmp_path / sibling.name).symlink_to(sibling)
    checked = check_document(read_document(source), tmp_path, load_sysrep_dir(sysreps))
    assert checked["problems"] == []
    saved = tmp_path / f"saved_{name}"
    saved.write_text(checked["xml"])
    assert meaning(load_procedure(saved)) == meaning(load_procedure(source))


def test_author_a_procedure_by_drag_and_drop_save_it_and_run_it(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    alice.goto(f"{server.url}/author")
    expect(alice.locator("#check-state")).to_have_text("1 problem(s)")  # a new procedure's empty step
    expect(alice.locator("#canvas .canvas-step .problem")).to_have_count(1)
    for field, value in (("#proc-id", "authored_pick"), ("#proc-title", "Pick a filter (authored in the browser)")):
        alice.fill(field, value)
        alice.press(field, "Tab")
    alice.locator('#proc-uses input[value="affordance_templates"]').check()
    at = '#palette-sysreps section[data-sysrep="affordance_templates"]'

    # add the template, keeping its instance as the result "at"
    drop(alice, f'{at} li[data-command="add_affordance_template"]', 0)
    set_arg(alice, "1.1", "affordance_template", "cdra_filter")
    set_attr(alice, "1.1", "result", "at")
    # the operator records the frame to pick from
    drop(alice, '#palette-kinds li[data-kind="record"]', 1)
    set_attr(alice, "1.2", "name", "pick_frame")
    card(alice, "1.2").locator(".item-text").fill("Frame of the filter to pick (e.g. filter/CDRA-F-0012)")
    card(alice, "1.2").locator(".item-text").press("Tab")
    # register the AT there: the id from the result, the frame from the recorded input
    drop(alice, f'{at} li[data-command="set_display_object_pose"]', 2)
    set_arg(alice, "1.3", "affordance_template", "cdra_filter")
    bind_arg(alice, "1.3", "id", "${at.id}")
    set_arg(alice, "1.3", "display_object", "cdra_filter")
    bind_arg(alice, "1.3", "frame", "${pick_frame}")
    expect(card(alice, "1.3").locator('.arg[data-arg="x"] .arg-value')).to_have_attribute("type", "number")
    # plan, verify the plan, execute
    drop(alice, f'{at} li[data-command="plan_trajectory"]', 3)
    set_arg(alice, "1.4", "affordance_template", "cdra_filter")
    set_arg(alice, "1.4", "trajectory", "grasp_and_pull")
    drop(alice, f'{at} li[data-telemetry="plan_valid"]', 4)
    expect(card(alice, "1.5")).to_have_class(re.compile(r"\bhas-problem\b"))  # a verify needs a test
    set_attr(alice, "1.5", "equals", "true")
    drop(alice, f'{at} li[data-command="execute_plan"]', 5)
    set_arg(alice, "1.6", "affordance_template", "cdra_filter")
    set_arg(alice, "1.6", "trajectory", "grasp_and_pull")

    expect(alice.locator("#check-state")).to_have_text("lint: no problems")
    expect(alice.locator("#canvas .card.has-problem")).to_have_count(0)
    alice.evaluate("window.scrollTo(0, 0)")  # the picture from the top: the file, its lint state, the procedure
    screenshot(alice, "web_author.png")
    alice.fill("#save-name", "authored_pick.xml")
    alice.click("#save")
    expect(alice.locator("#check-state")).to_have_text("saved authored_pick.xml")

    saved = server.procedures / "authored_pick.xml"
    lint = subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "lint", str(saved)], capture_output=True, text=True, timeout=60
    )
    assert lint.returncode == 0, lint.stdout + lint.stderr
    assert "${pick_frame}" in saved.read_text()

    # and it runs in the web view
    alice.goto(server.url)
    alice.select_option("#start-procedure", "authored_pick.xml")
    alice.select_option("#start-binding", "iva.yaml")
    alice.check("#start-form input[name=mode][value=autonomous]")
    alice.check("#start-rehearsal")  # just authored: a draft, rehearsed on the IVA simulator
    alice.click("#start-button")
    record = instruction(alice, "1.2")
    expect_current(record)
    record.locator("input.record-value").fill("filter/CDRA-F-0012")
    record.locator("button.record").click()
    expect(alice.locator("#run-status")).to_have_text("completed", timeout=120_000)
    expect(instruction(alice, "1.3").locator(".raw-detail")).to_contain_text("frame=filter/CDRA-F-0012")
    expect(instruction(alice, "1.6").locator(".detail")).to_contain_text("SUCCEEDED")


def _start_refused(page: Page, server: WebServer, *, rehearsal: bool) -> Locator:
    """Try to start the latch procedure from the form; the start error shown."""
    page.goto(server.url)
    page.select_option("#start-procedure", CRITICAL)
    page.select_option("#start-binding", "iva.yaml")
    page.set_checked("#start-rehearsal", rehearsal)
    page.click("#start-button")
    return page.locator("#start-error")


def _open_in_author(page: Page, server: WebServer) -> None:
    page.goto(f"{server.url}/author")
    page.select_option("#open-name", CRITICAL)
    page.click("#open")
    expect(page.locator("#release-state")).to_contain_text(CRITICAL)


def test_a_draft_runs_only_as_a_marked_rehearsal_a_second_operator_releases_it_and_an_edited_release_is_refused(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    expect(_start_refused(alice, server, rehearsal=False)).to_contain_text(
        f"procedures/{CRITICAL} is a draft (never released): a second operator reviews and releases it on the "
        "Author page, or run it as a rehearsal on a simulator"
    )

    # alice asks for its release; she may not release it herself, bob reviews and releases it
    _open_in_author(alice, server)
    expect(alice.locator("#release-state")).to_contain_text("draft, never released")
    alice.click("#ask-release")
    expect(alice.locator("#release-state")).to_contain_text("alice asks for its release")
    expect(alice.locator("#release")).to_be_disabled()
    refused = alice.request.post(
        f"{server.url}/api/author/procedures/{CRITICAL}/release",
        data={"action": "release", "sha256": alice.evaluate("author.version.sha256")},
        headers={"X-CSRF-Token": alice.evaluate("author.me.csrf")},
    )
    assert refused.status == 409 and "a second operator must review and release" in refused.json()["error"]
    bob = sign_in("bob")
    _open_in_author(bob, server)
    bob.click("#release")
    expect(bob.locator("#release-state")).to_contain_text("release 1 (released by bob, asked by alice)")
    screenshot(bob, "web_author_released.png")

    # the released version runs, marked with its release and hash
    alice.goto(server.url)
    start_run(alice, CRITICAL, "manual", rehearsal=False)
    expect(alice.locator("#run-version")).to_have_text(re.compile(r"^release 1 · sha256 [0-9a-f]{8}…$"))
    stop_run(alice, "released version checked")

    # edited after its release: refused with both hashes, and runs only as a rehearsal, marked so everywhere
    path = server.procedures / CRITICAL
    path.write_text(path.read_text().replace("</procedure>", "<!-- edited after release 1 -->\n</procedure>"))
    expect(_start_refused(alice, server, rehearsal=False)).to_have_text(
        re.compile(
            rf"^procedures/{CRITICAL} changed since release 1 \(sha256 [0-9a-f]{{8}}… → [0-9a-f]{{8}}…\); "
            "release it again or run it as a rehearsal$"
        )
    )
    run_id = start_run(alice, CRITICAL, "manual", rehearsal=True)
    expect(alice.locator("#run-version")).to_contain_text("REHEARSAL · draft, not released · sha256 ")
    expect(audit_row(alice, "run_started", "", "alice")).to_contain_text("REHEARSAL on a simulator, a draft")
    screenshot(alice, "web_rehearsal.png")
    stop_run(alice, "rehearsal checked")
    report = alice.request.get(f"{server.url}/runs/{run_id}/report")
    assert report.status == 200 and "REHEARSAL on a simulator, a draft, not released" in report.text()
    log = AuditLog(server.database.url)
    try:
        started = log.events(run_id)[0]
    finally:
        log.close()
    assert (started.data.to_json()["rehearsal"], started.data.to_json()["release"]) == (True, None)


def test_a_hazardous_command_waits_for_a_second_operator_on_another_console_and_never_for_the_senders_own(
    open_page: Callable[[WebServer, str], Page], server: WebServer, tmp_path: Path
) -> None:
    second = start_server(tmp_path, server.procedures, database=server.database, rosbridge=[])
    try:
        alice = open_page(server, "alice")
        run_id = start_run(alice, CRITICAL, "autonomous", rehearsal=True)
        unlock = instruction(alice, UNLOCK)
        expect_current(unlock)
        expect(alice.locator("#hold")).to_contain_text(f"Hazardous command {UNLOCK}: Unlock Filter")
        unlock.locator("button.confirm").click()
        expect(alice.locator("#confirm-text")).to_contain_text("Send it for a second operator's approval")
        alice.click("#confirm-yes")
        expect(alice.locator("#hold")).to_contain_text("Waits for a second operator's approval")

        # alice sent it: she is offered no Approve…, and her approval through the console's API
        # all the same is refused, with the reason, on the record; nothing is sent
        expect(unlock.locator(".approval-wait")).to_have_text("waiting for another operator")
        expect(unlock.locator("button.approve")).to_be_hidden()
        alice.evaluate("(number) => act('approve', {instruction: number})", UNLOCK)
        expect(alice.locator("#action-error")).to_contain_text(
            f"alice asked for {UNLOCK} to be sent: a second operator must approve it, not alice"
        )
        expect(audit_row(alice, "action_refused", UNLOCK, "alice")).to_contain_text("by the two person rule")
        expect(audit_row(alice, "approval_requested", UNLOCK, "alice")).to_contain_text("Unlock Filter")
        expect(audit_row(alice, "command_sent", UNLOCK, "PAX")).to_have_count(0)

        # bob, at another console, sees the request in words and approves it: it is sent at once
        bob = open_page(second, "bob")
        wanted = bob.locator(f'#run-list li[data-run-id="{run_id}"] .approval-wanted')  # in the list, not opened
        expect(wanted).to_contain_text(
            f"{UNLOCK}: Unlock Filter — sent by alice, waits for a second operator's approval"
        )
        bob.goto(f"{second.url}/#run={run_id}")
        expect(bob.locator("#hold")).to_contain_text("Waits for a second operator's approval")
        expect(bob.locator("#hold")).to_contain_text(f"{UNLOCK} waits for a second operator's approval (sent by alice)")
        expect(bob.locator("#hold")).to_contain_text("Unlock Filter")
        screenshot(bob, "web_approval_request.png")
        instruction(bob, UNLOCK).locator("button.approve").click()
        expect(bob.locator("#confirm-text")).to_contain_text("alice sent it for approval")
        bob.click("#confirm-yes")
        expect_ended(alice, "completed")
        expect(audit_row(alice, "command_sent", UNLOCK, "PAX")).to_contain_text("sent by alice, approved by bob")
        expect(unlock.locator(".mark")).to_contain_text("sent for approval by alice, approved by bob")
        expect(alice.locator("#action-error")).to_have_text("")  # the run moved on: her refusal is past
    finally:
        second.process.stop()

    log = AuditLog(server.database.url)
    try:
        events = log.events(run_id)
        assert log.verify(run_id).ok
    finally:
        log.close()
    by_kind = [(e.kind, e.actor) for e in events if e.instruction == UNLOCK and e.kind.value.startswith("approval_")]
    assert by_kind == [(EventKind.APPROVAL_REQUESTED, "alice"), (EventKind.APPROVAL_GIVEN, "bob")]
    sent = [e for e in events if e.kind is EventKind.COMMAND_SENT]
    assert [
        (e.instruction, e.data.to_json().get("requested_by"), e.data.to_json().get("approved_by")) for e in sent
    ] == [
        (UNLOCK, "alice", "bob"),
        ("1.4", None, None),  # lock_filter is no hazardous command
    ]
