"""The smaller defects of the operator console (issue 16, item 8), each shown fixed in a real browser.

On the simulated systems (conftest.py's server): the audit log reads as lines, the runs list
keeps itself current and marks rehearsals, Continue only where it can do something (and in the
banner after a halt with nothing moving), a stale click refused and on the record, a refusal's
words gone once the run moves on, resume from the web view, no overflow on narrow screens, a
report without Python reprs or clipped labels, and Save that asks before it replaces a procedure.
"""

from __future__ import annotations

import re
from collections.abc import Callable

import pytest
from playwright.sync_api import Page, expect

from procedure_language.parser import load_procedure
from support.operator_page import (
    IVA,
    audit_row,
    expect_current,
    expect_ended,
    instruction,
    screenshot,
    start_run,
    stop_run,
    unlock_approved_by,
)
from support.web_server import REPO, WebServer


def test_the_audit_log_reads_in_lines_with_values_not_json(sign_in: Callable[[str], Page]) -> None:
    alice = sign_in("alice")
    start_run(alice, IVA, "autonomous")
    unlock_approved_by(alice, "bob")
    expect(alice.locator("#hold")).to_contain_text("2.6: Confirm")
    sent = audit_row(alice, "command_sent", "1.3", "PAX")
    expect(sent).to_contain_text('sent Add Affordance Template "cdra_filter" (hide waypoints: false)')
    expect(sent).not_to_contain_text("affordance_templates.")  # the call itself only behind the raw switch
    expect(audit_row(alice, "command_result", "1.3", "PAX")).to_contain_text(
        "succeeded: added cdra_filter · id 0, instance cdra_filter:0"
    )
    details = alice.locator("#audit li .audit-detail")
    widths = details.evaluate_all("nodes => nodes.map((node) => node.getBoundingClientRect().width)")
    assert len(widths) > 20 and min(widths) > 250, widths  # the whole panel's width, not a table column's sliver
    lines = sent.locator(".audit-detail").evaluate(
        "node => node.getBoundingClientRect().height / parseFloat(getComputedStyle(node).lineHeight)"
    )
    assert lines <= 3, lines
    text = "\n".join(details.all_inner_texts())
    assert '{"' not in text and '":' not in text
    stop_run(alice, "audit log read")


def test_the_runs_list_marks_only_active_runs_live_and_updates_by_itself(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    run_id = start_run(alice, "web_walkthrough.xml", "manual")
    listed = alice.locator(f'#run-list li[data-run-id="{run_id}"]')
    expect(listed).to_have_class(re.compile(r"\blive\b"))
    expect(listed.locator(".run-status")).to_have_text("running")
    expect(listed.locator(".badge.version")).to_have_text("REHEARSAL")  # as its header says (a draft, on a simulator)
    alice.goto(f"{server.url}/#")  # alice now watches no run: only the list can tell her

    bob = sign_in("bob")
    bob.goto(f"{server.url}/#run={run_id}")
    expect(bob.locator("#connection")).to_have_attribute("data-state", "open")
    stop_run(bob, "stopped from another console")
    expect(listed.locator(".run-status")).to_have_text("stopped")  # without a click on refresh
    expect(listed).not_to_have_class(re.compile(r"\blive\b"))
    # The mark is read again until it shows: the row may be redrawn by a later push meanwhile.
    alice.wait_for_function(
        """(id) => { const n = document.querySelector(`#run-list li[data-run-id="${id}"] .run-status`);
                     return !!n && getComputedStyle(n, '::before').content === '"■"'; }""",
        arg=run_id,
    )


def test_continue_is_offered_only_where_automation_can_continue(sign_in: Callable[[str], Page]) -> None:
    alice = sign_in("alice")
    start_run(alice, "web_walkthrough.xml", "manual")
    alice.click("#pause")
    expect(audit_row(alice, "paused", "1.1", "alice")).to_have_count(1)
    expect(alice.locator("#pause")).to_be_disabled()
    expect(alice.locator("#continue")).to_be_disabled()  # in manual mode there is no automation to continue
    expect(alice.locator("#hold .hold-meta")).to_contain_text("automation is paused for when the run goes autonomous")
    alice.click("#mode-autonomous")
    expect(alice.locator("#hold")).to_contain_text("Automation paused at 1.1")
    expect(alice.locator("#continue")).to_be_enabled()
    alice.click("#continue")
    expect(alice.locator("#hold")).to_contain_text("2.1 failed")  # PAX went on by itself
    expect(alice.locator("#continue")).to_be_disabled()
    stop_run(alice, "continue checked")


def test_a_stale_click_is_refused_on_the_record_and_a_halt_with_nothing_moving_offers_continue(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    run_id = start_run(alice, "web_walkthrough.xml", "manual")
    instruction(alice, "1.1").locator("button.perform").click()
    expect_current(instruction(alice, "2.1"))
    # a click on an instruction the run has left (a page a moment behind): refused, with the rule, on the record
    alice.evaluate("(number) => act('perform', {instruction: number})", "1.1")
    expect(alice.locator("#action-error")).to_contain_text("1.1 is not the current instruction (the run is at 2.1)")
    expect(audit_row(alice, "action_refused", "1.1", "alice")).to_contain_text(
        "refused perform by the current instruction rule: 1.1 is not the current instruction"
    )
    # bob, at his console, HALTs while nothing moves: the run holds at 2.1; on alice's page the
    # refusal goes (the run moved on) and the banner offers the way on
    bob = sign_in("bob")
    bob.goto(f"{server.url}/#run={run_id}")
    expect(bob.locator("#connection")).to_have_attribute("data-state", "open")
    bob.click("#halt")
    expect(alice.locator("#hold")).to_have_attribute("data-tone", "halted")
    expect(alice.locator("#action-error")).to_have_text("")
    go_on = alice.locator("#hold-continue")
    expect(go_on).to_have_text("Continue")
    go_on.click()
    expect(audit_row(alice, "continued", "2.1", "alice")).to_have_count(1)
    expect(alice.locator("#hold")).not_to_have_attribute("data-tone", "halted")
    expect(go_on).to_be_hidden()
    stop_run(alice, "halt with nothing moving checked")


def test_a_stopped_run_is_resumed_from_the_web_view(sign_in: Callable[[str], Page], server: WebServer) -> None:
    alice = sign_in("alice")
    run_id = start_run(alice, "web_walkthrough.xml", "manual")
    instruction(alice, "1.1").locator("button.perform").click()
    expect(instruction(alice, "1.1").locator(".mark")).to_contain_text("completed by alice")
    stop_run(alice, "shift change")
    expect_ended(alice, "stopped")
    expect(alice.locator("#hold")).to_contain_text("Run stopped by alice: shift change")

    carol = sign_in("carol")  # observers may look at it, not resume it
    carol.goto(f"{server.url}/#run={run_id}")
    expect(carol.locator("#connection")).to_have_text("past run (from the audit log)")
    expect(carol.locator("#resume")).to_be_hidden()

    bob = sign_in("bob")  # the next shift, on another console
    bob.goto(f"{server.url}/#run={run_id}")
    expect(bob.locator("#connection")).to_have_text("past run (from the audit log)")
    bob.click("#resume")
    expect(bob.locator("#resume-dialog")).to_be_visible()
    bob.select_option("#resume-binding", "iva.yaml")
    bob.click("#resume-yes")
    expect(bob.locator("#connection")).to_have_attribute("data-state", "open")
    expect(bob.locator("#run-status")).to_have_text("active")
    expect(instruction(bob, "1.1").locator(".mark")).to_contain_text("completed by alice")
    expect_current(instruction(bob, "2.1"))
    expect(audit_row(bob, "run_resumed", "2.1", "bob")).to_have_count(1)
    expect(audit_row(bob, "run_stopped", "2.1", "alice")).to_contain_text("stopped: shift change")
    instruction(bob, "2.1").locator("button.skip").click()
    bob.fill("#skip-reason", "no ready pose here")
    bob.click("#skip-yes")
    expect(instruction(bob, "2.1").locator(".mark")).to_contain_text("skipped by bob")
    stop_run(bob, "resume checked")


@pytest.mark.parametrize(
    "server", ["sqlite"], indirect=True
)  # the page only: the log is tested on both databases elsewhere
@pytest.mark.parametrize("width", [1024, 800])
def test_nothing_runs_off_the_screen_at_narrow_widths(sign_in: Callable[[str], Page], width: int) -> None:
    alice = sign_in("alice")
    alice.set_viewport_size({"width": width, "height": 900})
    start_run(alice, IVA, "autonomous")
    unlock_approved_by(alice, "bob")
    expect(alice.locator("#hold")).to_contain_text("2.6: Confirm")
    overflowing = alice.evaluate("""() => {
        const width = document.documentElement.clientWidth;
        const found = [];
        if (document.documentElement.scrollWidth > width)
            found.push(`the page is ${document.documentElement.scrollWidth} px wide`);
        for (const node of document.querySelectorAll('#main-view *')) {
            if (!node.getClientRects().length || node.closest('dialog')) continue;
            const box = node.getBoundingClientRect();
            const name = `${node.tagName.toLowerCase()}.${node.className}`;
            if (box.right > width + 1) found.push(`${name} ends at ${Math.round(box.right)} px`);
            if (node.clientWidth && node.scrollWidth > node.clientWidth + 1
                && getComputedStyle(node).overflowX === 'visible')
                found.push(`${name} holds ${node.scrollWidth} px in ${node.clientWidth} px`);
        }
        return found;
    }""")
    assert overflowing == [], overflowing
    widths = alice.locator("#audit li .audit-detail").evaluate_all(
        "nodes => nodes.map((node) => node.getBoundingClientRect().width)"
    )
    assert min(widths) > 250, widths
    screenshot(alice, f"web_narrow_{width}.png")
    stop_run(alice, f"checked at {width} px")


def test_the_report_shows_values_as_read_and_whole_step_titles(
    sign_in: Callable[[str], Page], server: WebServer
) -> None:
    alice = sign_in("alice")
    run_id = start_run(alice, IVA, "autonomous")
    unlock_approved_by(alice, "bob")
    expect(alice.locator("#hold")).to_contain_text("2.6: Confirm")
    stop_run(alice, "report checked")
    report = alice.context.new_page()
    report.goto(f"{server.url}/runs/{run_id}/report")
    text = report.locator("body").inner_text()
    assert "SUCCEEDED" in text and "'SUCCEEDED'" not in text and "{'" not in text and "True" not in text
    assert "saw Execution Status = SUCCEEDED ✓" in text  # the SysRep's label, as the procedure view names it
    assert "affordance_templates." not in text  # the calls as sent only in a raw report
    labels = report.locator("svg text.step-label")
    expect(labels).to_have_count(len(load_procedure(REPO / "procedures" / IVA).steps))  # one per step
    assert labels.nth(1).text_content() == "2. Remove the dirty filter from the CDRA filter system"
    lefts = labels.evaluate_all("nodes => nodes.map((node) => node.getBBox().x)")
    assert min(lefts) >= 0, lefts  # no label starts left of the picture


@pytest.mark.parametrize(
    "server", ["sqlite"], indirect=True
)  # the page only: the log is tested on both databases elsewhere
def test_author_save_asks_before_replacing_a_procedure(sign_in: Callable[[str], Page], server: WebServer) -> None:
    alice = sign_in("alice")
    alice.goto(f"{server.url}/author")
    alice.select_option("#open-name", "web_walkthrough.xml")
    alice.click("#open")
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")
    alice.fill("#save-name", "console_copy.xml")
    alice.click("#save")
    expect(alice.locator("#check-state")).to_have_text("saved console_copy.xml")
    saved = server.procedures / "console_copy.xml"
    first = saved.read_text()

    alice.fill("#proc-title", "Walk-through, second version")
    alice.press("#proc-title", "Tab")
    expect(alice.locator("#check-state")).to_have_text("lint: no problems")
    alice.click("#save")
    expect(alice.locator("#replace-dialog")).to_be_visible()
    expect(alice.locator("#replace-name")).to_have_text("console_copy.xml")
    alice.click("#replace-cancel")
    expect(alice.locator("#author-error")).to_have_text("not saved: the file exists and was kept")
    assert saved.read_text() == first

    alice.click("#save")
    alice.click("#replace-yes")
    expect(alice.locator("#check-state")).to_have_text("saved console_copy.xml")
    assert 'title="Walk-through, second version"' in saved.read_text()
