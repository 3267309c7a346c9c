"""The console's flight controls (issue 16) in Chromium, on the simulated IVA systems.

HALT during a motion (the simulated arm moves until a cancel reaches it), an outcome that is not
known (a capture whose first reply is lost: the page says so in neither green nor red, and
"Ask again" sends the same key), a record re-entered with both values in the log, a step back,
an observer who can act on nothing (the act refused on the record), and a second run on a
controlled robot refused with who controls it (the refused start on the record), then taken over
with a reason logged in both runs. The same on the real IVA stack,
with the arm's joint states, is in test_web_on_real_stack.py.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Any

from playwright.sync_api import Page, expect
from sqlalchemy import select

from pride.events import EventKind
from records.audit_log import AuditLog
from records.audit_schema import audit_records
from support.operator_page import audit_row, expect_current, instruction, screenshot, start_run, stop_run
from support.web_server import WebServer

FLIGHT = "web_flight_controls.xml"
WALKTHROUGH = "web_walkthrough.xml"
UNKNOWN_INK = "rgb(106, 44, 145)"  # style.css --unknown: neither the green of done nor the red of failed


def answer(page: Page, reason: str, value: str | None = None) -> None:
    """Fill the page's reason dialog (and its new value) and confirm it."""
    if value is not None:
        page.fill("#reason-value", value)
    page.fill("#reason-input", reason)
    page.click("#reason-yes")


def test_halt_unknown_outcome_correction_and_step_back(sign_in: Callable[[str], Page], server: WebServer) -> None:
    alice = sign_in("alice")
    start_run(alice, FLIGHT, "manual")
    expect(alice.locator("#halt")).to_be_enabled()
    expect(alice.locator("#robot-link")).to_have_attribute("data-state", "connected")

    record = instruction(alice, "1.1")
    record.locator(".record-value").fill("CDRA-F-0012")
    record.locator("button.record").click()
    expect(record).to_have_attribute("data-status", "completed")
    instruction(alice, "1.2").locator("button.perform").click()
    expect(instruction(alice, "1.2")).to_have_attribute("data-status", "completed")

    # the capture's reply is lost: neither done nor failed, and the page says what is needed
    capture = instruction(alice, "1.3")
    capture.locator("button.perform").click()
    expect(alice.locator("#hold")).to_have_attribute("data-tone", "unknown")
    expect(alice.locator("#hold .hold-what")).to_have_text("Outcome unknown")
    expect(capture).to_have_attribute("data-status", "outcome_unknown")
    expect(capture.locator(".mark")).to_contain_text("outcome unknown")
    assert capture.locator(".mark").evaluate("node => getComputedStyle(node).color") == UNKNOWN_INK
    expect(audit_row(alice, "command_result", "1.3", "alice")).to_contain_text("OUTCOME UNKNOWN")
    expect(alice.locator("#ask-again")).to_be_visible()
    screenshot(alice, "console-outcome-unknown.png")
    alice.click("#ask-again")  # the same key again: this time the answer comes
    expect(capture).to_have_attribute("data-status", "completed")
    retries = alice.locator('#audit li[data-kind="command_sent"][data-instruction="1.3"]')
    expect(retries).to_have_count(2)
    keys = {row.get_attribute("data-key") for row in retries.all()}
    assert len(keys) == 1 and None not in keys, keys

    # the wrong filter was entered: re-enter it; both values are in the log and the text follows
    check = instruction(alice, "1.4")
    expect(check.locator(".line > .text")).to_contain_text("CDRA-F-0012")
    record.locator("button.correct").click()
    expect(alice.locator("#reason-value")).to_have_value("CDRA-F-0012")
    answer(alice, "label misread", value="CDRA-F-0013")
    expect(audit_row(alice, "record_corrected", "1.1", "alice")).to_contain_text(
        "CDRA-F-0012 → CDRA-F-0013: label misread"
    )
    expect(check.locator(".line > .text")).to_contain_text("CDRA-F-0013")
    expect(record.locator(".mark")).to_contain_text("re-entered by alice: CDRA-F-0012 → CDRA-F-0013")

    # back to the picture, for the right filter; its reply is lost again and alice records what she saw
    capture.locator("button.go-back").click()
    answer(alice, "picture of the right filter")
    expect(alice.locator('#audit li[data-kind="stepped_back"][data-actor="alice"]')).to_contain_text("went back to 1.3")
    expect_current(capture)
    capture.locator("button.perform").click()
    expect(capture).to_have_attribute("data-status", "outcome_unknown")
    alice.click("#resolve-succeeded")
    answer(alice, "the image is in the ground store")
    expect(capture).to_have_attribute("data-status", "completed")
    expect(capture.locator(".mark")).to_contain_text(
        "outcome recorded as succeeded by alice: the image is in the ground store"
    )
    check.locator("button.done").click()

    # the long reach moves until HALT: the instruction is halted by alice, never completed
    alice.click("#mode-autonomous")
    reach = instruction(alice, "2.1")
    expect(reach).to_have_attribute("data-status", "executing")
    alice.fill("#halt-reason", "crew member in the way")
    alice.focus("#halt")
    alice.keyboard.press("Enter")  # from the keyboard too (a pointer acts on the press: the real-stack tests)
    expect(reach).to_have_attribute("data-status", "halted")
    expect(alice.locator('#audit li[data-kind="halt"]')).to_have_count(1)
    expect(reach.locator(".mark")).to_contain_text("halted by alice")
    expect(alice.locator("#hold")).to_have_attribute("data-tone", "halted")
    expect(alice.locator("#hold .hold-text")).to_contain_text("by alice: crew member in the way")
    expect(audit_row(alice, "halt", "2.1", "alice")).to_contain_text("HALT: crew member in the way")
    expect(audit_row(alice, "command_result", "2.1", "PAX")).to_contain_text("HALTED")
    expect(alice.locator('#audit li[data-kind="instruction_completed"][data-instruction="2.1"]')).to_have_count(0)
    screenshot(alice, "console-halted.png")

    # an observer sees it all and can act on nothing, in the page or through the API
    carol = sign_in("carol")
    carol.goto(alice.url)
    expect(carol.locator("#hold")).to_have_attribute("data-tone", "halted")
    expect(carol.locator("#halt")).to_be_disabled()
    token = {"X-CSRF-Token": carol.evaluate("view.me.csrf")}
    refused = carol.request.post(
        f"{server.url}/api/runs/{carol.evaluate('view.runId')}/actions",
        headers=token,
        data={"action": "halt", "reason": "not mine to halt"},
    )
    assert refused.status == 403 and "observer" in refused.json()["error"], refused.text()
    expect(audit_row(alice, "action_refused", "", "carol")).to_contain_text(
        "refused halt by the observers watch rule: carol is an observer"
    )
    stop_run(alice, "flight controls checked")


def test_a_second_run_on_a_controlled_robot_is_refused_then_taken_over(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    first = start_run(alice, WALKTHROUGH, "manual")
    bob = sign_in("bob")
    bob.select_option("#start-procedure", WALKTHROUGH)
    bob.select_option("#start-binding", "iva.yaml")
    bob.check("#start-rehearsal")
    before = _refusals(server, "bob")
    bob.click("#start-button")
    expect(bob.locator("#start-error")).to_contain_text(f"controlled by run {first} (user alice")
    # the refused start is on the record, under an id of its own (no run started)
    assert [
        (run_id.split("-refused-")[0], data["rule"], data["asked"])
        for run_id, data in _refusals(server, "bob")
        if (run_id, data) not in before
    ] == [
        (
            "web_walkthrough",
            "one_run_per_robot",
            {"procedure": WALKTHROUGH, "binding": "iva.yaml", "mode": "manual", "rehearsal": True},
        )
    ]
    take_over = bob.locator("#take-over")
    expect(take_over).to_have_text("Take over iva from alice…")
    take_over.click()
    expect(bob.locator("#reason-text")).to_contain_text(f"run {first} of alice")
    answer(bob, "alice's console froze")
    expect(bob.locator("#run-id")).not_to_have_text(first)
    expect(bob.locator("#connection")).to_have_attribute("data-state", "open")
    second = bob.locator("#run-id").inner_text()
    expect(bob.locator('#audit li[data-kind="control_taken"][data-actor="bob"]')).to_contain_text(
        f"took control of iva from run {first} (alice): alice's console froze"
    )

    # alice's run holds, says who took the robot, and offers to take it back
    expect(alice.locator("#hold .hold-what")).to_have_text("Robot taken over")
    expect(alice.locator("#hold .hold-text")).to_contain_text("bob")
    expect(alice.locator('#audit li[data-kind="control_lost"]')).to_contain_text(
        f"taken over by bob (run {second}): alice's console froze"
    )
    expect(alice.locator("#take-control")).to_be_visible()
    stop_run(bob, "takeover checked")
    stop_run(alice, "takeover checked")


def _refusals(server: WebServer, actor: str) -> list[tuple[str, dict[str, Any]]]:
    """The run id and data of every refused act of ``actor`` in the server's audit log."""
    log = AuditLog(server.database.url)
    try:
        with log.engine.connect() as connection:
            rows = connection.execute(
                select(audit_records.c.run_id, audit_records.c.data).where(
                    audit_records.c.kind == EventKind.ACTION_REFUSED.value, audit_records.c.actor == actor
                )
            ).all()
    finally:
        log.close()
    return [(row.run_id, json.loads(row.data)) for row in rows]
