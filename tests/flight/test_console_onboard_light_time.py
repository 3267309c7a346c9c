"""The IVA procedure onboard across 60 s of light time each way: it completes, and a console action
sent during it is shown on its way, then answered, never "outcome unknown" nor "no news".

At 60 s one way the unit reaches the habitat three and a half round trips of 2 minutes after the
runner opens its connection (TCP, TLS, the upgrade; the unit goes right behind the login), and
the habitat's answer to an operator's action is due 130 s after it went up (round trip + 10 s of
work): far later than a console waits for any request (30 s after the host took it). The console
must show the action on its way, with the ground clock's time its answer is due, and then the
answer. ``caretaker run --onboard --at-consoles`` supervises the IVA procedure in the ground
namespace through ``caretaker link --delay 60`` (the simulation flat out: time scale 0); the
clean filter's id is not given, so the habitat holds at the record 4.1; the operator enters it in
Chromium at ``caretaker serve``; the run then completes, every command and motion once, and the
ground's record is the habitat's chain. Every wait here is the light-time rule's
(:class:`LightTime`), as the product's are. How a flight is set up: flight_support.py.
"""

from __future__ import annotations

import re
import time

import pytest

from onboard.downlink import ACTION_WORK_S, UNIT_LIFETIME_S
from rosbridge_wire.light_time import LightTime
from support.operator_page import expect_current
from support.second_operator import APPROVED_BY_BOB

from .flight_support import CLEAN_FILTER, PROCEDURE, RUN_TIMEOUT_S, assert_flown_exactly_once, flight, result_of

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=700), pytest.mark.timeout(3600)]

#: One way, s: Mars at its nearest is three minutes; this is long enough that every wait across
#: the link is minutes, and the action's answer is due long after a console stops waiting.
FAR = 60.0
OPERATOR, PASSWORD = "far-op", "answers-from-far-away"
#: What the page says of actions and of the habitat, as it changes (an "outcome unknown" or a
#: "no news" shown for a moment counts).
_RECORD = """() => {
  window.pageSaid = [];
  const note = () => {
    const now = ['#action-news', '#action-error', '#robot-link', '#hold']
      .map((id) => document.querySelector(id).textContent).join(' | ');
    if (window.pageSaid.at(-1) !== now) window.pageSaid.push(now);
  };
  new MutationObserver(note).observe(document.querySelector('#run-view') || document.body,
    {subtree: true, childList: true, characterData: true, attributes: true});
}"""


def test_the_iva_procedure_onboard_at_60_s_one_way_completes_and_an_action_is_on_its_way_then_answered(
    ros_env: dict[str, str],
) -> None:
    from playwright.sync_api import expect

    light = LightTime(FAR)
    due_after = light.answer_within(ACTION_WORK_S)  # 130 s
    with flight(ros_env, delay=FAR, time_scale="0", onboard=True) as f:
        serve, url = f.serve_console(OPERATOR, PASSWORD)
        runner = f.hosts.caretaker(
            f.hosts.ground,
            *("run", str(PROCEDURE), "--binding", str(f.binding), "--auto", "--user", OPERATOR),
            *("--db", f.db_url, "--confirm-manual", *APPROVED_BY_BOB, "--rehearsal", "--onboard", "--at-consoles"),
            ready=r"^READY run ",
            timeout=light.connect_within + light.answer_within(UNIT_LIFETIME_S),  # connected, then the unit's answer
        )
        run_id = runner.wait_for_line(r"^READY run ", 1).split()[2]
        with f.console_page(url, OPERATOR, PASSWORD) as page:
            page.locator("#main-view").wait_for(state="visible")
            page.evaluate(f"location.hash = 'run={run_id}'")
            page.evaluate(_RECORD)
            record = page.locator('#procedure li.instruction[data-number="4.1"]')
            # the habitat holds there once it has done steps 1 to 3, and the ground hears so
            expect_current(record, timeout=1000 * light.answer_within(RUN_TIMEOUT_S))
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
            # due a round trip and the habitat's work after it went up, which is after the click (the
            # page shows whole seconds): bounded below here, above once the habitat's receipt is read
            assert expected >= due_after - 1, (said, expected)
            # the answer, a round trip and more after the click: shown when it came, before it was due
            expect(news).to_have_attribute("data-state", "done", timeout=1000 * due_after)
            expect(news).to_contain_text("enter: on the habitat:")
            run_id_, status = result_of(runner, light.answer_within(RUN_TIMEOUT_S))
            expect(page.locator("#hold")).to_contain_text("Run completed")
            seen: list[str] = page.evaluate("window.pageSaid")
            assert not [s for s in seen if "unknown" in s or "no news" in s], seen
            assert not page.locator("#action-error").inner_text()
        serve.stop()
        assert run_id_ == run_id
        assert_flown_exactly_once(f, run_id, status)
        ground, habitat = f.ground_chain(run_id), f.habitat.onboard_chain(run_id)
        assert [(e.seq, e.hash) for e in ground] == [(e.seq, e.hash) for e in habitat]
        taken = [(a["action"], a["user"], a["state"]) for a in f.habitat.onboard_actions()]
        assert taken == [("enter", OPERATOR, "DONE")], taken  # once, as the page said
        # It went up no later than one light time before the habitat received it (the link delays it
        # by FAR at least; the habitat's own work only adds): a due time counted from when the ground
        # sent it, however long a crowded ground took to send it after the click.
        [entered] = f.habitat.onboard_actions()
        went_up_by = entered["received"] - FAR - clicked
        assert expected <= went_up_by + due_after + 1, (said, expected, went_up_by)
