"""The operator's console on the ground host, flying the IVA procedure across the link, in a browser.

``caretaker serve`` runs in the ground namespace with the ground binding (wss://, secret, 1.3 s
link); Chromium runs in the ground namespace too (Playwright drives it through a pipe), as an
operator's browser on the ground network would. The connection to the habitat is reset for 10 s
while the pull-out executes: the page must show the link lost (since when, commands in flight)
and then back, and the pull-out's real outcome once the ledger has told it.

The page's link banner is ``#robot-link`` (``data-state`` ``lost``/``connected``); the audit list
shows the executive's LINK_LOST / LINK_RESTORED records.
"""

from __future__ import annotations

import re

import pytest

from support.operator_page import expect_current

from .flight_support import LINK_MS, PULL_OUT, flight, start_from_console

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=85)]

OPERATOR, PASSWORD = "flight", "flight-over-the-link"


def test_the_console_shows_a_lost_link_and_the_real_outcome_after_it(ros_env: dict[str, str]) -> None:
    from playwright.sync_api import expect

    with flight(ros_env, delay=1.3, time_scale="1") as f:
        serve, url = f.serve_console(OPERATOR, PASSWORD)
        with f.console_page(url, OPERATOR, PASSWORD) as page:
            start_from_console(page, f, onboard=False)  # the PAX host opens its link to the habitat first
            expect(page.locator("#connection")).to_have_attribute("data-state", "open", timeout=LINK_MS)
            expect(page.locator("#robot-link")).to_have_attribute("data-state", "connected", timeout=LINK_MS)
            confirm = page.locator('#procedure li.instruction[data-number="2.6"]')
            expect_current(confirm, timeout=240_000)
            confirm.locator("button.done").click()
            f.await_execution(PULL_OUT)
            f.link.control.reset(10)
            link = page.locator("#robot-link")
            expect(link).to_have_attribute("data-state", "lost", timeout=LINK_MS)
            expect(link).to_contain_text(re.compile(r"lost since .*1 command in flight"), timeout=LINK_MS)
            expect(page.locator('#audit li[data-kind="link_lost"]')).to_have_count(1, timeout=LINK_MS)
            expect(link).to_have_attribute("data-state", "connected", timeout=120_000)
            expect(page.locator('#audit li[data-kind="link_restored"]')).to_have_count(1, timeout=LINK_MS)
            pull = page.locator('#procedure li.instruction[data-number="2.7"]')
            expect(pull.locator(".detail")).to_contain_text("Result: succeeded", timeout=120_000)
            page.click("#stop")
            page.fill("#stop-reason", "link check done")
            page.click("#stop-yes")
            expect(page.locator("#run-status")).to_have_text("stopped", timeout=LINK_MS)
        serve.stop()
