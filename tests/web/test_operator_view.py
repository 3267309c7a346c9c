"""The operator web view in a real browser, on a real ``caretaker serve`` process.

Issue #6's acceptance: sign in; start the IVA procedure in manual mode; Send the first command
and see its result and the audit record with the user's id; switch to autonomous and watch PAX
stop at the manual instruction; enter a record value and see it passed to the next command; an
observer watching the same run cannot Send, and the server refuses it when forced.
"""

from __future__ import annotations

import re
from pathlib import Path

from playwright.sync_api import Page, expect

from web_server import procedure_shelf, start_server
from pride.audit_log import AuditLog

REPO = Path(__file__).resolve().parents[2]
IMAGES = REPO / "docs" / "images"
IVA = "iva_cdra_filter_replacement.xml"


def start_run(page: Page, procedure: str, mode: str) -> str:
    page.select_option("#start-procedure", procedure)
    page.select_option("#start-binding", "iva.yaml")
    page.check(f"#start-form input[name=mode][value={mode}]")
    page.click("#start-button")
    expect(page.locator("#connection")).to_have_attribute("data-state", "open")
    run_id = page.locator("#run-id").inner_text()
    assert run_id.startswith(procedure.removesuffix(".xml"))
    return run_id


def instruction(page: Page, number: str):
    return page.locator(f'#procedure li.instruction[data-number="{number}"]')


def audit_row(page: Page, kind: str, number: str, actor: str):
    return page.locator(f'#audit tbody tr[data-kind="{kind}"][data-instruction="{number}"][data-actor="{actor}"]')


def test_operator_runs_the_iva_procedure_and_an_observer_only_watches(sign_in, server) -> None:
    alice = sign_in("alice")
    expect(alice.locator("#who")).to_have_text("alice (operator)")
    run_id = start_run(alice, IVA, "manual")
    expect(alice.locator("#run-mode")).to_have_text("manual")
    expect(alice.locator("#proc-title")).to_contain_text("IVA CDRA Filter Replacement")

    # the procedure as written: numbering, notes/cautions, automatable icons, live telemetry
    expect(instruction(alice, "2.1")).to_contain_text("2.1")
    expect(alice.locator("#procedure .notice.note").first).to_contain_text("registered to the filter")
    expect(alice.locator("#procedure .notice.caution").first).to_contain_text("within reach of the CDRA cabinet")
    expect(instruction(alice, "1.3").locator(".auto-icon")).to_have_attribute("title", re.compile("PAX can run this"))
    expect(instruction(alice, "1.1").locator(".telemetry")).to_contain_text(
        re.compile(r"affordance_templates\.affordance_template_server_active = true · \d+\.\d s ago"))
    expect(instruction(alice, "1.1")).to_have_class(re.compile(r"\bcurrent\b"))

    # manual mode: the operator checks the two verifies, then Sends the first command
    instruction(alice, "1.1").locator("button.perform").click()
    expect(instruction(alice, "1.1").locator(".mark")).to_contain_text("completed by alice")
    instruction(alice, "1.2").locator("button.perform").click()
    expect(instruction(alice, "1.3")).to_have_class(re.compile(r"\bcurrent\b"))
    send = instruction(alice, "1.3").locator("button.perform")
    expect(send).to_have_text("Send")
    send.click()
    expect(instruction(alice, "1.3").locator(".detail")).to_contain_text("result: success — added cdra_filter")
    expect(instruction(alice, "1.3").locator(".mark")).to_contain_text("completed by alice")
    expect(audit_row(alice, "command_sent", "1.3", "alice")).to_contain_text("add_affordance_template")
    expect(audit_row(alice, "command_result", "1.3", "alice")).to_contain_text("success")

    # an observer opens the same run in another browser and sees it live, without controls
    carol = sign_in("carol")
    expect(carol.locator("#start-panel")).to_be_hidden()
    carol.goto(f"{server.url}/#run={run_id}")
    expect(carol.locator("#connection")).to_have_attribute("data-state", "open")
    expect(instruction(carol, "1.3").locator(".mark")).to_contain_text("completed by alice")
    expect(instruction(carol, "1.4").locator("button.perform")).to_be_disabled()
    expect(carol.locator("#mode-autonomous")).to_be_disabled()
    forced = carol.request.post(f"{server.url}/api/runs/{run_id}/actions",
                                data={"action": "perform", "instruction": "1.4"})
    assert forced.status == 403, forced.text()
    assert "observer" in forced.json()["error"]
    assert carol.request.post(f"{server.url}/api/runs", data={"procedure": IVA, "binding": "iva.yaml"}).status == 403

    # autonomous: PAX runs on and holds at the manual instruction 2.6; both browsers see it
    alice.click("#mode-autonomous")
    expect(alice.locator("#run-mode")).to_have_text("autonomous")
    for page in (alice, carol):
        expect(instruction(page, "2.6")).to_have_class(re.compile(r"\bcurrent\b"))
        expect(page.locator("#hold")).to_contain_text("2.6: Confirm that the area in front of the CDRA cabinet is clear")
    expect(instruction(alice, "2.5").locator(".mark")).to_contain_text("completed by PAX")
    expect(instruction(alice, "2.1").locator(".detail")).to_contain_text('frame="cabinet/slot"')
    expect(audit_row(alice, "awaiting_operator", "2.6", "PAX")).to_have_count(1)
    expect(instruction(carol, "2.6").locator("button.done")).to_be_disabled()
    instruction(alice, "2.6").scroll_into_view_if_needed()
    alice.screenshot(path=str(IMAGES / "web_autonomous_hold.png"))

    # Done lets PAX carry on to the record at 4.1; the operator takes over in manual mode
    instruction(alice, "2.6").locator("button.done").click()
    expect(instruction(alice, "4.1")).to_have_class(re.compile(r"\bcurrent\b"))
    expect(alice.locator("#hold")).to_contain_text("4.1")
    alice.click("#mode-manual")
    expect(alice.locator("#run-mode")).to_have_text("manual")
    record = instruction(alice, "4.1")
    record.locator("input.record-value").fill("twelve")
    record.locator("button.record").click()  # the browser's own check stops it first
    expect(record.locator("input.record-value:invalid")).to_have_count(1)
    record.locator("input.record-value").evaluate("input => input.removeAttribute('pattern')")
    record.locator("button.record").click()  # past the page, the executive validates
    expect(alice.locator("#action-error")).to_contain_text("does not match the pattern")
    record.locator("input.record-value").fill("CDRA-F-0012")
    record.locator("button.record").click()
    expect(record.locator(".detail")).to_contain_text('recorded "CDRA-F-0012"')
    expect(audit_row(alice, "operator_input", "4.1", "alice")).to_contain_text('clean_filter_id = "CDRA-F-0012"')
    instruction(alice, "4.2").locator("button.perform").click()
    expect(instruction(alice, "4.2").locator(".detail")).to_contain_text('frame="filter/CDRA-F-0012"')
    expect(audit_row(alice, "command_sent", "4.2", "alice")).to_contain_text('"frame":"filter/CDRA-F-0012"')
    expect(audit_row(carol, "command_sent", "4.2", "alice")).to_have_count(1)
    alice.screenshot(path=str(IMAGES / "web_manual_record.png"))
    instruction(carol, "4.2").scroll_into_view_if_needed()
    carol.screenshot(path=str(IMAGES / "web_observer.png"))

    # step, pause, continue and stop, each recorded as alice's
    alice.click("#step")
    expect(instruction(alice, "4.3").locator(".mark")).to_contain_text("completed by alice")
    alice.click("#pause")
    expect(audit_row(alice, "paused", "4.4", "alice")).to_have_count(1)
    alice.click("#mode-autonomous")
    expect(alice.locator("#hold")).to_have_text("automation paused at 4.4")
    alice.click("#continue")
    expect(alice.locator("#hold")).to_contain_text("5.1: Confirm the cabinet slot is empty")
    alice.once("dialog", lambda dialog: dialog.accept())
    alice.click("#stop")
    for page in (alice, carol):
        expect(page.locator("#run-status")).to_have_text("stopped")
    expect(audit_row(alice, "run_stopped", "5.1", "alice")).to_have_count(1)

    # the audit log holds every action with its user, and nothing from the observer
    log = AuditLog(f"sqlite:///{server.db}")
    try:
        events = log.events(run_id)
    finally:
        log.close()
    actors = {e.actor for e in events}
    assert actors == {"alice", "PAX"}, actors
    sent = [e for e in events if e.kind.value == "command_sent" and e.instruction == "4.2"]
    assert sent and sent[0].data["args"]["frame"] == "filter/CDRA-F-0012" and sent[0].actor == "alice"


def test_breakpoint_failure_retry_skip_and_hazard_confirmation(sign_in, server) -> None:
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
    expect(stale.locator(".telemetry")).to_have_attribute("data-stale", "true")
    expect(stale.locator(".telemetry")).to_contain_text(re.compile(r'cdra\.installed_filter_condition = "dirty" · \d+\.\d s ago · STALE'))
    expect(stale.locator(".mark")).to_contain_text('cdra.installed_filter_condition was stale \'dirty\'')
    stale.locator("button.skip").click()
    alice.fill("#skip-reason", "condition sensor offline; checked by eye")
    alice.click("#skip-yes")
    expect(stale.locator(".mark")).to_contain_text("skipped by alice")

    # the manual instruction holds automation until Done
    expect(instruction(alice, "3.1")).to_have_class(re.compile(r"\bcurrent\b"))
    instruction(alice, "3.1").locator("button.done").click()

    # the hazardous command waits for a confirmation, given in a dialog, even in autonomous mode
    hazardous = instruction(alice, "3.2")
    expect(hazardous.locator(".hazard")).to_be_visible()
    expect(alice.locator("#hold")).to_contain_text("3.2 is hazardous")
    hazardous.locator("button.confirm").click()
    expect(alice.locator("#confirm-dialog")).to_be_visible()
    expect(alice.locator("#confirm-text")).to_contain_text("3.2: Send cdra.unlock_filter()")
    alice.screenshot(path=str(IMAGES / "web_hazard_confirmation.png"))
    alice.click("#confirm-yes")
    expect(audit_row(alice, "confirmation", "3.2", "alice")).to_have_count(1)
    expect(audit_row(alice, "command_sent", "3.2", "PAX")).to_have_count(1)

    # PAX stops at the breakpoint; Continue finishes the run
    expect(alice.locator("#hold")).to_contain_text("breakpoint at 3.3")
    expect(instruction(alice, "3.3").locator(".telemetry")).to_contain_text("cdra.filter_locked = false")
    alice.click("#continue")
    expect(alice.locator("#run-status")).to_have_text("completed")
    expect(instruction(alice, "3.3").locator(".mark")).to_contain_text("completed by PAX")
    instruction(alice, "3.2").scroll_into_view_if_needed()
    alice.screenshot(path=str(IMAGES / "web_completed_run.png"))

    # the run is in the list of runs, with its after-action report
    alice.click("#refresh-runs")
    listed = alice.locator(f'#run-list li[data-run-id="{run_id}"]')
    expect(listed).to_contain_text("web_walkthrough")
    report = alice.request.get(server.url + listed.locator("a.report-link").get_attribute("href"))
    assert report.status == 200, report.text()
    assert run_id in report.text() and "alice" in report.text()


def test_eva_inspection_shows_sub_procedures_and_the_camera_images(sign_in, server) -> None:
    alice = sign_in("alice")
    alice.select_option("#start-procedure", "eva_inspection.xml")
    alice.select_option("#start-binding", "eva.yaml")
    alice.click("#start-button")
    expect(alice.locator("#connection")).to_have_attribute("data-state", "open")

    # a breakpoint inside the called sub-procedure, right after the arm's first motion
    instruction(alice, "2.1/1.5").locator("button.breakpoint").click()
    expect(instruction(alice, "2.1/1.5")).to_have_class(re.compile(r"\bhas-breakpoint\b"))
    alice.click("#mode-autonomous")
    expect(alice.locator("#hold")).to_contain_text("breakpoint at 2.1/1.5")

    # the camera view followed the arm while it moved (live captures, not audit records)
    camera = alice.locator("#camera")
    expect(alice.locator("#camera-caption")).to_contain_text(re.compile(r"live view while the robot moves .*_web_view\.png"))
    assert camera.evaluate("image => image.decode().then(() => image.naturalWidth)") == 160
    live_image = camera.get_attribute("src")
    expect(audit_row(alice, "command_sent", "2.1/1.4", "PAX")).to_contain_text("execute_plan")
    expect(alice.locator('#audit tbody tr[data-kind="command_sent"]', has_text="camera.capture")).to_have_count(0)
    alice.click("#continue")

    # PAX runs into the called sub-procedure and holds at the operator's assessment of target A
    assessment = instruction(alice, "2.1/2.2")
    expect(assessment).to_have_class(re.compile(r"\bcurrent\b"))
    expect(instruction(alice, "2.1/2.1").locator(".mark")).to_contain_text("completed by PAX")
    expect(alice.locator("#camera-caption")).to_contain_text(re.compile(r"^2\.1/2\.1 · .*hull_a\.png"))
    first_image = camera.get_attribute("src")
    assert first_image != live_image
    alice.screenshot(path=str(IMAGES / "web_camera.png"))

    # the operator answers; PAX retreats, moves to target B and shows its new image
    assessment.locator("select.record-value").select_option("false")
    assessment.locator("button.record").click()
    expect(instruction(alice, "3.1/2.2")).to_have_class(re.compile(r"\bcurrent\b"))
    expect(alice.locator("#camera-caption")).to_contain_text("hull_b.png")
    assert camera.get_attribute("src") != first_image
    expect(audit_row(alice, "operator_input", "2.1/2.2", "alice")).to_contain_text("damage = false")


def test_a_past_run_is_drawn_from_the_audit_log_alone(sign_in, server, browser, tmp_path) -> None:
    alice = sign_in("alice")
    run_id = start_run(alice, "web_walkthrough.xml", "manual")
    instruction(alice, "1.1").locator("button.perform").click()
    expect(instruction(alice, "1.1").locator(".mark")).to_contain_text("completed by alice")

    # another server on the same audit log: the run is not live there, only recorded
    other = start_server(tmp_path, procedure_shelf(tmp_path), db=server.db)
    try:
        context = browser.new_context(viewport={"width": 1500, "height": 1000})
        try:
            page = context.new_page()
            page.goto(other.url)
            page.fill("#user-id", "carol")
            page.click("#sign-in-form button[type=submit]")
            page.click(f'#run-list li[data-run-id="{run_id}"] a[href^="#run="]')
            expect(page.locator("#connection")).to_have_text("past run (from the audit log)")
            expect(instruction(page, "1.1").locator(".mark")).to_contain_text("completed by alice")
            expect(instruction(page, "1.1").locator(".detail")).to_contain_text("result: success — added cdra_filter")
            expect(page.locator("#controls")).to_be_hidden()
            expect(audit_row(page, "command_result", "1.1", "alice")).to_have_count(1)
        finally:
            context.close()
    finally:
        other.process.stop()
