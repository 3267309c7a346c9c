"""The operator's console on the ground host, flying the IVA procedure across the link, in a browser.

Its 3D view shows the motions before the pull-out honestly across the light time: the arm's age,
the arm never drawn beyond what the habitat reported, and the path it was told to follow.

``caretaker serve`` runs in the ground namespace with the ground binding (wss://, secret, 1.3 s
link); Chromium runs in the ground namespace too (Playwright drives it through a pipe), as an
operator's browser on the ground network would. The connection to the habitat is reset for 10 s
while the pull-out executes: the page must show the link lost (since when, commands in flight)
and then back, and the pull-out's real outcome once the ledger has told it.

The page's link banner is ``#robot-link`` (``data-state`` ``lost``/``connected``); the audit list
shows the executive's LINK_LOST / LINK_RESTORED records.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import pytest

from support.operator_page import expect_current, unlock_approved_by

from .flight_support import DELAY, LINK_MS, PULL_OUT, flight, start_from_console

if TYPE_CHECKING:
    from playwright.sync_api import Page

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=85), pytest.mark.timeout(900)]

OPERATOR, PASSWORD = "flight", "flight-over-the-link"
SHOTS = Path(os.environ["CARETAKER_SCREENSHOTS"]) if os.environ.get("CARETAKER_SCREENSHOTS") else None
#: Records what the 3D view draws, ten times a second from the page's start: motions over the link
#: come and go while the run waits on round trips, so they are read afterwards, none missed.
_RECORD = """() => {
  window.viewSamples = [];
  setInterval(() => {
    const view = window.caretakerSpatial;
    if (!view || !view.robot || window.viewSamples.length >= 3000) return;
    const v = view.inspect();
    window.viewSamples.push({age: v.arm_age_s, said: view.ageEl.hidden ? null : view.ageEl.textContent,
                             commanded: v.commanded, drawn: v.joints_drawn, reports: v.joints_reported_recently});
  }, 100);
}"""


def _what_the_view_drew_across_the_link(page: Page) -> None:
    """While the arm moved, the view said how old the arm drawn was (at least the light time), drew
    it only between states the habitat reported (per joint, within the last reports' range: never
    ahead of them), and drew the path it had been told to follow (from the moment the ground sent
    the motion)."""
    samples: list[dict[str, Any]] = page.evaluate("window.viewSamples")
    moving = [b for a, b in zip(samples, samples[1:], strict=False) if a["drawn"] != b["drawn"]]
    assert moving, f"the arm was never drawn moving ({len(samples)} samples of the view)"
    for sample in moving:
        assert sample["age"] is not None and sample["age"] >= DELAY - 0.1, sample["age"]
        assert re.fullmatch(r"arm as reported \d+\.\d s ago", sample["said"] or ""), sample["said"]
        for joint, drawn in sample["drawn"].items():
            reported = [r[joint] for r in sample["reports"] if joint in r]
            assert reported and min(reported) - 1e-9 <= drawn <= max(reported) + 1e-9, (
                f"{joint} drawn at {drawn}, beyond what the habitat reported ({min(reported)}..{max(reported)})"
            )
    commanded = {s["commanded"]["trajectory"] for s in moving if s["commanded"]["visible"]}
    # the ground sent each motion: its path is drawn from then, a light time before the arm moves
    assert commanded, "no motion was drawn with the path the arm had been told to follow"
    print(
        f"3D view over the {DELAY} s link: {len(moving)} samples of the arm moving, its age "
        f"{min(s['age'] for s in moving):.2f}-{max(s['age'] for s in moving):.2f} s; the commanded path shown "
        f"while moving: {', '.join(sorted(commanded))}"
    )
    if SHOTS is not None:
        page.locator("#spatial-view").screenshot(path=str(SHOTS / "spatial-iva-over-the-link.png"))


def test_the_console_shows_a_lost_link_and_the_real_outcome_after_it(ros_env: dict[str, str]) -> None:
    from playwright.sync_api import expect

    with flight(ros_env, delay=DELAY, time_scale="1") as f:
        serve, url = f.serve_console(OPERATOR, PASSWORD)
        with f.console_page(url, OPERATOR, PASSWORD, webgl=True) as page:
            page.evaluate(_RECORD)
            start_from_console(page, f, onboard=False)  # the PAX host opens its link to the habitat first
            expect(page.locator("#connection")).to_have_attribute("data-state", "open", timeout=LINK_MS)
            expect(page.locator("#robot-link")).to_have_attribute("data-state", "connected", timeout=LINK_MS)
            # a guard, not a measure: 31 instructions from the ground, one round trip each, 4 motions, 3
            # locates; on the way the operator sends the hazardous unlock for approval, and bob approves it
            unlock_approved_by(page, "bob", timeout=480_000)
            confirm = page.locator('#procedure li.instruction[data-number="2.6"]')
            expect_current(confirm, timeout=480_000)
            _what_the_view_drew_across_the_link(page)
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
