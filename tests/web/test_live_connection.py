"""The run's live connection: a page that opens its run again, or loses its connection, still shows
every audit event and keeps what its operator has entered and not yet recorded.

On the simulated systems (simulated_systems.py). The IVA procedure, its unlock approved by a
second operator, holds at 2.6 (an operator's Done) and records nothing more while it waits, so
the audit list can be compared with the run's whole record.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterator

import pytest
from playwright.sync_api import Page, Route, expect

from support.operator_page import IVA, audit_row, expect_current, instruction, start_run, stop_run, unlock_approved_by


@pytest.fixture
def held(sign_in: Callable[[str], Page]) -> Iterator[tuple[Page, int]]:
    """Alice's page on an IVA run held at 2.6, and the sequence number of its last event; stopped
    afterwards (the suite's server has one IVA robot, which a run left live would keep controlling)."""
    page = sign_in("alice")
    start_run(page, IVA, "autonomous")
    unlock_approved_by(page, "bob")  # hazardous: bob approves it
    expect_current(instruction(page, "2.6"))
    yield page, int(page.evaluate("view.state.last_seq"))
    stop_run(page, "test done")


def expect_every_event_once(page: Page, last_seq: int) -> None:
    """The audit list shows events 1..last_seq, each once."""
    expect(page.locator("#audit li")).to_have_count(last_seq)
    shown = page.locator("#audit li .seq").all_inner_texts()
    assert sorted(int(seq.removeprefix("#")) for seq in shown) == list(range(1, last_seq + 1)), shown


def test_opening_the_run_again_before_the_first_opening_finished_shows_every_event_once(held: tuple[Page, int]) -> None:
    page, last_seq = held

    # what a hash change while signing in does: two openings, the second asked before the first is drawn
    page.evaluate("() => { openRun(view.runId); openRun(view.runId); }")
    expect(page.locator("#connection")).to_have_attribute("data-state", "open")
    expect_every_event_once(page, last_seq)


def test_a_lost_connection_whose_reopening_fails_is_tried_again(held: tuple[Page, int]) -> None:
    page, last_seq = held
    run_id = page.locator("#run-id").inner_text()
    failed: list[str] = []

    def busy_once(route: Route) -> None:
        if failed or route.request.method != "GET":
            route.continue_()
            return
        failed.append(route.request.url)
        route.fulfill(status=503, json={"error": "the console is busy"})

    page.route(f"**/api/runs/{run_id}", busy_once)
    page.evaluate("() => view.socket.close()")  # the connection drops (not closed by the page's own opening)
    expect(page.locator("#action-error")).to_have_text("the console is busy")
    assert failed, "the page did not open its run again after losing the connection"
    expect(page.locator("#connection")).to_have_attribute("data-state", "reconnecting")

    expect(page.locator("#connection")).to_have_attribute("data-state", "open")
    expect(page.locator("#connection")).to_have_attribute("title", re.compile(r"^lost at .+: the console is busy$"))
    expect(page.locator("#action-error")).to_have_text("")
    expect_every_event_once(page, last_seq)


def test_a_lost_connection_leaves_the_instructions_an_operator_is_using_as_they_are(
    held: tuple[Page, int],
) -> None:
    """Reopened after a lost connection, the run is not drawn again: the field being typed in keeps
    its entry and focus, and a button under the pointer is still the one clicked."""
    page, _ = held
    instruction(page, "2.6").locator("button.done").click()
    record = instruction(page, "4.1")
    expect_current(record)
    field = record.locator("input.record-value")
    field.fill("CDRA-F-0012")
    record.evaluate("item => { item.dataset.drawnBefore = 'yes'; }")
    openings = page.evaluate("view.opening")

    page.evaluate("() => view.socket.close()")  # the connection drops; the page opens the run again
    page.wait_for_function("n => view.opening > n", arg=openings)
    expect(page.locator("#connection")).to_have_attribute("data-state", "open")
    expect(page.locator("#connection")).to_have_attribute("title", re.compile(r"^lost at .+: closed with code \d+$"))
    expect(page.locator("#procedure li[data-drawn-before]")).to_have_count(1)  # the same node, not a new one
    expect(field).to_have_value("CDRA-F-0012")
    expect(field).to_be_focused()

    record.locator("button.record").click()
    expect(audit_row(page, "operator_input", "4.1", "alice")).to_contain_text("recorded clean filter id = CDRA-F-0012")
