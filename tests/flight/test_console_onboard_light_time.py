"""A console action on an onboard run across 14 s of light time each way: on its way, then answered.

At 14 s one way the habitat's answer to an operator's action comes 28 s and more after it went up,
and is due 38 s after (round trip + 10 s of work), later than a console waits for any request
(30 s after the host took it): the console must show it on its way, with the ground clock's time
its answer is due, and then the answer, never "outcome unknown". ``caretaker run --onboard
--at-consoles`` supervises the IVA procedure in the ground namespace through ``caretaker link
--delay 14``; the clean filter's id is not given,
so the habitat holds at the record 4.1; the operator enters it in Chromium at ``caretaker serve``.
How a flight is set up: flight_support.py.
"""

from __future__ import annotations

import re
import time

import pytest

from support.operator_page import expect_current
from support.second_operator import APPROVED_BY_BOB

from .flight_support import CLEAN_FILTER, PROCEDURE, flight

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=240), pytest.mark.timeout(1200)]

#: One way, s: the action's answer is due (38 s) after a console stops waiting for a request.
FAR = 14.0
OPERATOR, PASSWORD = "far-op", "answers-from-far-away"
#: Everything the page says of actions, as it changes (an "outcome unknown" shown for a moment counts).
_RECORD = """() => {
  window.actionSaid = [];
  const note = () => window.actionSaid.push(
    document.querySelector('#action-news').textContent + ' | ' + document.querySelector('#action-error').textContent);
  new MutationObserver(note).observe(document.querySelector('#run-view') || document.body,
    {subtree: true, childList: true, characterData: true, attributes: true});
}"""


def test_an_onboard_action_at_14_s_one_way_is_shown_on_its_way_then_answered(ros_env: dict[str, str]) -> None:
    from playwright.sync_api import expect

    with flight(ros_env, delay=FAR, time_scale="0", onboard=True) as f:
        serve, url = f.serve_console(OPERATOR, PASSWORD)
        runner = f.hosts.caretaker(
            f.hosts.ground,
            *("run", str(PROCEDURE), "--binding", str(f.binding), "--auto", "--user", OPERATOR),
            *("--db", f.db_url, "--confirm-manual", *APPROVED_BY_BOB, "--rehearsal", "--onboard", "--at-consoles"),
            ready=r"^READY run ",
            timeout=600,  # opening the connection takes four round trips of 28 s
        )
        run_id = runner.wait_for_line(r"^READY run ", 1).split()[2]
        with f.console_page(url, OPERATOR, PASSWORD) as page:
            page.locator("#main-view").wait_for(state="visible")
            page.evaluate(f"location.hash = 'run={run_id}'")
            record = page.locator('#procedure li.instruction[data-number="4.1"]')
            expect_current(record, timeout=400_000)  # the habitat holds there, and the ground heard so
            page.evaluate(_RECORD)
            record.locator("input.record-value").fill(CLEAN_FILTER)
            clicked = time.time()
            record.locator("button.record").click()
            news = page.locator("#action-news li.action-news")
            expect(news).to_have_attribute("data-state", "on_its_way", timeout=30_000)
            said = news.inner_text()
            due = re.fullmatch(r"enter: on its way to the habitat, answer expected at (\d\d):(\d\d):(\d\d) UTC", said)
            assert due, said
            hours, minutes, seconds = (int(part) for part in due.groups())
            expected = (hours * 3600 + minutes * 60 + seconds - clicked) % 86400  # due, counted from the click
            assert 2 * FAR + 10 - 2 <= expected <= 2 * FAR + 10 + 5, (said, expected)
            # the answer, 28 s and more after the click: shown when it came, before it was due
            expect(news).to_have_attribute("data-state", "done", timeout=120_000)
            expect(news).to_contain_text("enter: on the habitat:")
            seen: list[str] = page.evaluate("window.actionSaid")
            assert not [s for s in seen if "unknown" in s], seen
            assert not page.locator("#action-error").inner_text()
        serve.stop()
        runner.stop()
        taken = [(a["action"], a["user"], a["state"]) for a in f.habitat.onboard_actions()]
        assert taken == [("enter", OPERATOR, "DONE")], taken  # once, as the page said
