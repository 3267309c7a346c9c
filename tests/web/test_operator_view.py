"""The operator web view's controls in a real browser, on a real ``caretaker serve`` process.

These tests are about the page and its server, so the systems behind the executive are the
simulated ones of simulated_systems.py: a failing command and a stale sensor on demand,
deterministic camera images. The IVA acceptance run on the real robot stack is
test_web_on_real_stack.py; the record-to-command part of it, which needs the run past three steps of
robot motion, is here.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path

from playwright.sync_api import Browser, Page, expect

from pride.phrasing import format_value
from records.audit_log import AuditLog
from support.operator_page import (
    IVA,
    audit_row,
    expect_current,
    expect_ended,
    instruction,
    screenshot,
    shown_image_width,
    sign_in_on,
    start_run,
    stop_run,
    unlock_approved_by,
)
from support.web_server import WebServer, procedure_shelf, start_server


def test_a_recorded_value_goes_into_the_next_command_of_the_iva_procedure(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    run_id = start_run(alice, IVA, "autonomous")
    unlock_approved_by(alice, "bob")  # hazardous in the cdra SysRep: bob approves it

    # PAX holds at the manual instruction; Done lets it carry on to the record at 4.1
    expect(alice.locator("#hold")).to_contain_text("2.6: Confirm that the area in front of the CDRA cabinet is clear")
    instruction(alice, "2.6").locator("button.done").click()
    expect_current(instruction(alice, "4.1"))
    expect(alice.locator("#hold")).to_contain_text("4.1")
    alice.click("#mode-manual")
    expect(alice.locator("#run-mode")).to_have_text("manual")

    # the record is typed and validated: by the browser first, by the executive in any case
    record = instruction(alice, "4.1")
    record.locator("input.record-value").fill("twelve")
    record.locator("button.record").click()
    expect(record.locator("input.record-value:invalid")).to_have_count(1)
    record.locator("input.record-value").evaluate("input => input.removeAttribute('pattern')")
    record.locator("button.record").click()
    expect(record.locator(".record-error")).to_contain_text("does not match the pattern")  # next to the field
    record.locator("input.record-value").fill("CDRA-F-0012")
    record.locator("button.record").click()
    expect(record.locator(".detail")).to_contain_text("recorded CDRA-F-0012")
    expect(audit_row(alice, "operator_input", "4.1", "alice")).to_contain_text("recorded clean filter id = CDRA-F-0012")

    # the next instructions read with the recorded id in their sentences; Send puts it into the command
    expect(instruction(alice, "4.2").locator(".line > .text")).to_have_text(
        "Read which rack slot filter CDRA-F-0012 is seated in"
    )
    instruction(alice, "4.2").locator("button.perform").click()
    expect(instruction(alice, "4.2").locator(".raw-detail")).to_contain_text("filter_id=CDRA-F-0012")
    expect(instruction(alice, "4.2").locator(".raw-detail")).to_be_hidden()  # the raw command only on demand
    alice.check("#show-raw")
    expect(instruction(alice, "4.2").locator(".raw-detail")).to_be_visible()
    expect(instruction(alice, "4.2").locator(".raw").first).to_have_text(re.compile(r"^cdra\.slot_of_filter\("))
    alice.uncheck("#show-raw")
    expect(audit_row(alice, "command_sent", "4.2", "alice")).to_contain_text("Slot Of Filter for CDRA-F-0012")
    # the audit log reads the started instruction with the value it was started with, not the author's ${...}
    expect(audit_row(alice, "instruction_started", "4.2", "alice").locator(".audit-detail")).to_have_text(
        "started: Read which rack slot filter CDRA-F-0012 is seated in"
    )
    screenshot(alice, "web_manual_record.png")

    # step, pause, continue and stop, each recorded as alice's
    alice.click("#step")  # 4.3 calls the look, locate, register sub-procedure: a step goes into it
    expect_current(instruction(alice, "4.3/1.1"))
    alice.click("#step")
    expect(instruction(alice, "4.3/1.1").locator(".mark")).to_contain_text("completed by alice")
    alice.click("#pause")
    expect(audit_row(alice, "paused", "4.3/1.2", "alice")).to_have_count(1)
    alice.click("#mode-autonomous")
    expect(alice.locator("#hold")).to_contain_text("Automation paused at 4.3/1.2")
    alice.click("#continue")
    expect(alice.locator("#hold")).to_contain_text("5.1: Confirm the cabinet slot is empty")
    expect(audit_row(alice, "instruction_started", "4.7", "PAX").locator(".audit-detail")).to_have_text(
        "started: Pick clean filter CDRA-F-0012 from the rack"
    )
    stop_run(alice, "end of the walk-through")
    expect_ended(alice, "stopped")
    expect(audit_row(alice, "run_stopped", "5.1", "alice")).to_contain_text("end of the walk-through")

    log = AuditLog(server.database.url)
    try:
        sent = [e for e in log.events(run_id) if e.kind.value == "command_sent" and e.instruction == "4.2"]
    finally:
        log.close()
    assert [(e.actor, e.data.to_json()["args"]["filter_id"]) for e in sent] == [("alice", "CDRA-F-0012")]


def test_breakpoint_failure_retry_skip_and_hazard_confirmation(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    run_id = start_run(alice, "web_walkthrough.xml", "manual")

    # a breakpoint on 3.3, set while in manual mode
    instruction(alice, "3.3").locator("button.breakpoint").click()
    expect(instruction(alice, "3.3")).to_have_class(re.compile(r"\bhas-breakpoint\b"))
    expect(audit_row(alice, "breakpoint_set", "3.3", "alice")).to_have_count(1)

    # autonomous: 2.1 fails (its template was never added) and PAX holds with the reason
    alice.click("#mode-autonomous")
    failed = instruction(alice, "2.1")
    expect(failed.locator(".mark")).to_contain_text("failed by PAX")
    expect(failed.locator(".mark")).to_contain_text("no instance of 'ready_pose'")
    expect(alice.locator("#hold")).to_contain_text("2.1 failed")
    expect(alice.locator("#hold")).to_have_attribute("data-tone", "failure")  # red and ✗, never a hold's amber
    expect(alice.locator("#hold .hold-icon")).to_have_text("✗")
    failed.locator("button.retry").click()
    expect(audit_row(alice, "retry", "2.1", "alice")).to_have_count(1)
    expect(audit_row(alice, "instruction_failed", "2.1", "alice")).to_have_count(1)  # the retry, as alice
    failed.locator("button.skip").click()
    alice.fill("#skip-reason", "no ready pose in this walk-through")
    alice.click("#skip-yes")
    expect(failed.locator(".mark")).to_contain_text("skipped by alice")
    expect(failed.locator(".mark")).to_contain_text("no ready pose in this walk-through")

    # a verify on a stale value fails, and the value is marked stale where it is shown
    stale = instruction(alice, "2.2")
    expect(stale.locator(".telemetry")).to_have_attribute("data-state", "stale")
    expect(stale.locator(".telemetry")).to_contain_text(
        re.compile(r"Installed Filter Condition = dirty · \d+\.\d s ago · STALE")
    )
    expect(stale.locator(".mark")).to_contain_text("cdra.installed_filter_condition was stale 'dirty'")
    stale.locator("button.skip").click()
    alice.fill("#skip-reason", "condition sensor offline; checked by eye")
    alice.click("#skip-yes")
    expect(stale.locator(".mark")).to_contain_text("skipped by alice")

    # the manual instruction holds automation until Done
    expect_current(instruction(alice, "3.1"))
    instruction(alice, "3.1").locator("button.done").click()

    # the hazardous command waits, even in autonomous mode: alice sends it for approval in a dialog
    # (the IVA deployment's critical commanding), and a second operator, bob, approves it
    hazardous = instruction(alice, "3.2")
    expect(hazardous.locator(".hazard")).to_be_visible()
    expect(alice.locator("#hold")).to_contain_text("Hazardous command 3.2: Unlock Filter")
    expect(alice.locator("#hold")).to_have_attribute("data-tone", "hold")
    expect(hazardous.locator("button.confirm")).to_have_text("Send for approval…")
    hazardous.locator("button.confirm").click()
    expect(alice.locator("#confirm-dialog")).to_be_visible()
    expect(alice.locator("#confirm-text")).to_contain_text(
        "3.2: Unlock Filter. Send it for a second operator's approval"
    )
    screenshot(alice, "web_hazard_confirmation.png")
    alice.click("#confirm-yes")
    expect(audit_row(alice, "approval_requested", "3.2", "alice")).to_have_count(1)
    expect(alice.locator("#hold")).to_contain_text("Waits for a second operator's approval")
    bob = sign_in("bob")
    bob.goto(f"{server.url}/#run={run_id}")
    instruction(bob, "3.2").locator("button.approve").click()
    expect(bob.locator("#confirm-text")).to_contain_text("alice sent it for approval")
    bob.click("#confirm-yes")
    expect(audit_row(alice, "approval_given", "3.2", "bob")).to_have_count(1)
    expect(audit_row(alice, "command_sent", "3.2", "PAX")).to_contain_text("sent by alice, approved by bob")

    # PAX stops at the breakpoint; Continue finishes the run
    expect(alice.locator("#hold")).to_contain_text("Breakpoint at 3.3")
    expect(instruction(alice, "3.3").locator(".telemetry")).to_contain_text("Filter Locked = false")
    alice.click("#continue")
    expect_ended(alice, "completed")
    expect(instruction(alice, "3.3").locator(".mark")).to_contain_text("completed by PAX")
    instruction(alice, "3.2").scroll_into_view_if_needed()
    screenshot(alice, "web_completed_run.png")

    # the run is in the list of runs, with its after-action report
    alice.click("#refresh-runs")
    listed = alice.locator(f'#run-list li[data-run-id="{run_id}"]')
    expect(listed).to_contain_text("web_walkthrough")
    report = alice.request.get(server.url + listed.locator("a.report-link").get_attribute("href"))
    assert report.status == 200, report.text()
    assert run_id in report.text() and "alice" in report.text()


def test_eva_inspection_shows_sub_procedures_and_the_camera_images(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    alice.select_option("#start-procedure", "eva_inspection.xml")
    alice.select_option("#start-binding", "eva.yaml")
    alice.check("#start-rehearsal")
    alice.click("#start-button")
    expect(alice.locator("#connection")).to_have_attribute("data-state", "open")

    # a breakpoint inside the called sub-procedure, right after the arm's first motion
    instruction(alice, "2.1/1.5").locator("button.breakpoint").click()
    expect(instruction(alice, "2.1/1.5")).to_have_class(re.compile(r"\bhas-breakpoint\b"))
    alice.click("#mode-autonomous")
    expect(alice.locator("#hold")).to_contain_text("Breakpoint at 2.1/1.5")

    # the camera view followed the arm while it moved (live captures, not audit records)
    camera = alice.locator("#camera")
    expect(alice.locator("#camera-caption")).to_contain_text(
        re.compile(r"live view while the robot moves .*_web_view\.png")
    )
    assert shown_image_width(camera) == 160
    live_image = camera.get_attribute("src")
    expect(audit_row(alice, "command_sent", "2.1/1.4", "PAX")).to_contain_text("sent Execute Plan")
    expect(alice.locator('#audit li[data-kind="command_sent"]', has_text="Capture Image")).to_have_count(0)
    alice.click("#continue")

    # PAX runs into the called sub-procedure and holds at the operator's assessment of target A
    assessment = instruction(alice, "2.1/2.2")
    expect_current(assessment)
    expect(instruction(alice, "2.1/2.1").locator(".mark")).to_contain_text("completed by PAX")
    expect(alice.locator("#camera-caption")).to_contain_text(re.compile(r"^2\.1/2\.1 · .*hull_a\.png"))
    first_image = camera.get_attribute("src")
    assert first_image != live_image
    screenshot(alice, "web_camera.png")

    # nothing is chosen for the operator: Record on the untouched answer records nothing
    expect(assessment.locator("select.record-value")).to_have_value("")
    assessment.locator("button.record").click()
    expect(assessment.locator("select.record-value:invalid")).to_have_count(1)
    expect(audit_row(alice, "operator_input", "2.1/2.2", "alice")).to_have_count(0)

    # the operator answers; PAX retreats, moves to target B and shows its new image
    assessment.locator("select.record-value").select_option("false")
    assessment.locator("button.record").click()
    expect_current(instruction(alice, "3.1/2.2"))
    expect(alice.locator("#camera-caption")).to_contain_text("hull_b.png")
    assert camera.get_attribute("src") != first_image
    expect(audit_row(alice, "operator_input", "2.1/2.2", "alice")).to_contain_text("damage = false")


def test_a_past_run_is_drawn_from_the_audit_log_alone(
    sign_in: Callable[[str], Page], server: WebServer, browser: Browser, tmp_path: Path
) -> None:
    alice = sign_in("alice")
    run_id = start_run(alice, "web_walkthrough.xml", "manual")
    instruction(alice, "1.1").locator("button.perform").click()
    expect(instruction(alice, "1.1").locator(".mark")).to_contain_text("completed by alice")

    stop_run(alice, "seen from another console next")

    # another server on the same ground database, which never ran it: the run is only recorded
    other = start_server(tmp_path, procedure_shelf(tmp_path), database=server.database)
    try:
        context = browser.new_context(viewport={"width": 1500, "height": 1000})
        try:
            page = context.new_page()
            page.goto(other.url)
            sign_in_on(page, "carol")
            page.click(f'#run-list li[data-run-id="{run_id}"] a[href^="#run="]')
            expect(page.locator("#connection")).to_have_text("past run (from the audit log)")
            expect(instruction(page, "1.1").locator(".mark")).to_contain_text("completed by alice")
            expect(instruction(page, "1.1").locator(".detail")).to_contain_text("Result: succeeded — added cdra_filter")
            expect(page.locator("#controls")).to_be_hidden()
            expect(audit_row(page, "command_result", "1.1", "alice")).to_have_count(1)
        finally:
            context.close()
    finally:
        other.process.stop()


def test_a_page_load_asks_for_nothing_the_console_does_not_have(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    failed: list[str] = []
    alice.on("response", lambda r: failed.append(f"{r.status} {r.url}") if r.status >= 400 else None)
    alice.reload()
    expect(alice.locator("#run-list")).to_be_visible()
    # what a browser asks for on its own when a page names no icon (a run's report names none)
    icon = alice.request.get(f"{server.url}/favicon.ico")
    assert icon.ok and icon.headers["content-type"] == "image/svg+xml", icon.status
    assert alice.locator('link[rel="icon"]').get_attribute("href") == "/static/favicon.svg"
    assert failed == []


#: Values as runs report them, and the id that says what each measures (what the page knows of it).
ROUNDING: list[tuple[object, str]] = [
    (0.14999985294229648, "x"),
    (-3.397308328442832e-10, ""),
    (1.5707963, "yaw"),
    ([0.15, 0.45, 0.3, 0.0, 1.5708, 1.5708], "end_pose"),
    ([0.1, -0.5, 1.2, 0.0, 0.0, 3.14159], "joint_positions"),
    ([0.0049, 0.0, -0.0], "xyz_unnamed"),
    (12345.678, ""),
    (0.000012, ""),
    (7, ""),
    (2, "x"),
    ({"x": 0.35, "y": 0.0049, "yaw": 0.0, "plan_valid": True}, ""),
    (0.5, "speed"),
    (0.6552, "offset_mm"),  # perception's offset, already in millimetres (its sentence says "mm")
    (1.23456, "offset_deg"),
]


def test_the_page_rounds_values_as_the_report_and_the_terminal_do(sign_in: Callable[[str], Page]) -> None:
    page = sign_in("carol")
    shown = page.evaluate("cases => cases.map(([value, name]) => formatValue(value, name))", ROUNDING)
    assert shown == [format_value(value, name=name) for value, name in ROUNDING]
    assert shown[0] == "150 mm" and shown[3] == "position (150, 450, 300) mm, orientation (0, 90, 90)°"
    assert shown[-2:] == ["0.7", "1.2"]  # to 0.1 mm and 0.1°, not 0.6552
