"""A ground that re-attaches: the supervising runner stops mid-run, the run goes on on the habitat,
and an operator attaches a new supervisor from the console's runs list.

The first runner (``caretaker run --onboard`` at a terminal, without the clean filter's id that
4.1 records: the habitat's run holds there for an operator, so it outlasts the attaches however
loaded the machine) is stopped (SIGTERM) at the run's first motion, with the console already
open at the runs list: long before it could hear of the hold at 4.1 (unattended, it would stop
the run there). That motion, the move to the ready pose, is paced at a tenth of real time, and
after it come five more executions, three locates and their plans on the habitat (flat out),
and the news of the hold a light time later. The habitat never waits for
the ground, so the run goes on to 4.1; the runner ends its lease as it goes, so
the consoles list the run as one whose supervisor is gone, and offer Attach to operators (not to
observers, whom the console refuses all the same). Attach, in Chromium on the ground network,
starts ``caretaker run --attach RUN`` on the console's host with the console's binding and
rosbridge URL: it gets the unit the run started from from the habitat, catches the ground's
record up from the last event the first runner stored, hash for hash, hosts the run for the
consoles again. A second attach while it holds the run, from the console and from a terminal, is
refused and told who holds it; each attach and refusal is on the record. The operator then records
the clean filter's id on the console, across the link, and the run completes: the procedure's
steps 1 to 4 (``--to pick_clean``), to the pick of the filter recorded; the steps after it would
add motions, not news of the attach.
"""

from __future__ import annotations

import os
import re
import signal

import pytest

from caretaker.processes import VENV_BIN
from console.accounts import AccountStore
from records.audit_chain import verify_chain
from records.audit_log import AuditLog
from support.audit import attach_records
from support.operator_page import expect_current, instruction

from .flight_support import (
    CLEAN_FILTER,
    DELAY,
    LINK_MS,
    RUN_TIMEOUT_S,
    assert_flown_exactly_once,
    flight,
    result_of,
)

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=110), pytest.mark.timeout(900)]

OPERATOR, PASSWORD = "attach-op", "attaches-from-the-console"
OBSERVER, OBSERVER_PASSWORD = "watcher", "watches-the-habitat"
#: The last step run: the pick of the clean filter whose id the operator records at 4.1.
PICK_CLEAN_STEP = "pick_clean"
#: The run's first motion (to the ready pose), during which the first runner is stopped, and its pace.
FIRST_MOTION, FIRST_MOTION_PACE = "ready", 0.1


def test_a_run_whose_supervisor_stopped_is_attached_from_the_runs_list_and_a_second_attach_is_refused(
    ros_env: dict[str, str],
) -> None:
    from playwright.sync_api import expect

    with flight(ros_env, delay=DELAY, time_scale="0", paced={FIRST_MOTION: FIRST_MOTION_PACE}, onboard=True) as f:
        serve, url = f.serve_console(OPERATOR, PASSWORD)
        accounts = AccountStore(f.db_url)
        try:
            accounts.add(OBSERVER, "observer", OBSERVER_PASSWORD)
        finally:
            accounts.close()
        with f.console_page(url, OPERATOR, PASSWORD) as page:
            first = f.run("--onboard", "--to", PICK_CLEAN_STEP, record=False)
            run_id = first.wait_for_line(r"^READY run ", 120).split()[2]
            page.click("#refresh-runs")  # the list as it is now, the run in it
            line = page.locator(f'#run-list li[data-run-id="{run_id}"]')
            expect(line).to_have_attribute("data-host", re.compile(r"^runner .* for flight$"))  # who answers at it
            expect(line.locator("button.attach")).to_have_count(0)  # it has its supervisor
            f.await_execution(FIRST_MOTION)
            os.kill(first.proc.pid, signal.SIGTERM)  # supervision ends; the run does not
            assert result_of(first, 120) == (run_id, "detached")
            assert first.proc.wait(60) != 0
            stored = len(f.ground_chain(run_id))

            # the list says whose supervision ended, and offers operators to attach
            expect(line).to_have_attribute("data-status", "interrupted")
            expect(line.locator(".meta")).to_contain_text(" for flight went silent at ")
            browser = page.context.browser
            assert browser is not None
            watcher = browser.new_page()  # an observer, in a context of its own
            try:
                watcher.goto(url)
                watcher.fill("#user-id", OBSERVER)
                watcher.fill("#password", OBSERVER_PASSWORD)
                watcher.click("#sign-in-form button[type=submit]")
                seen = watcher.locator(f'#run-list li[data-run-id="{run_id}"]')
                expect(seen).to_have_attribute("data-status", "interrupted")
                expect(seen.locator("button.attach")).to_have_count(0)
                # refused all the same when asked (attach.js's own call, as a click would make it)
                watcher.evaluate("(runId) => attachRun(runId)", run_id)  # awaited: the answer is shown
                expect(watcher.locator("#runs-error")).to_contain_text(
                    f"{OBSERVER} is an observer: observers may watch, not attach"
                )
            finally:
                watcher.close()

            line.locator("button.attach").click()
            expect(page.locator("#run-id")).to_have_text(run_id, timeout=LINK_MS)
            expect(page.locator("#run-host")).to_have_text(re.compile(rf"^hosted by runner .* for {OPERATOR}$"))
            expect(page.locator("#robot-link")).to_contain_text("onboard run on the habitat")
            said = page.locator("#runs-error").inner_text()
            assert not said, said

            # a second attach while it is held: from a stale list, then at a terminal
            page.evaluate("(runId) => attachRun(runId)", run_id)
            expect(page.locator("#runs-error")).to_contain_text(
                f"run {run_id} has a supervisor: runner ", timeout=LINK_MS
            )
            expect(page.locator("#runs-error")).to_contain_text(f" for {OPERATOR} holds it")
            attach = ["run", "--attach", run_id, "--binding", str(f.binding), "--db", f.db_url]
            second = f.hosts.run(
                f.hosts.ground, [str(VENV_BIN / "caretaker"), *attach, "--user", "flight-3"], timeout=240, check=False
            )
            said = f"second:\n{second.stdout}{second.stderr}"
            assert second.returncode == 2 and "--attach refused" in second.stderr, said
            assert f"run {run_id} is live on runner " in second.stderr and f" for {OPERATOR} " in second.stderr, said

            # the run waited at 4.1 for an operator all along: the attached supervisor carries the answer up
            record = instruction(page, "4.1")
            expect_current(record, timeout=RUN_TIMEOUT_S * 1000)
            record.locator("input.record-value").fill(CLEAN_FILTER)
            record.locator("button.record").click()
            expect(page.locator("#run-status")).to_have_text("completed", timeout=RUN_TIMEOUT_S * 1000)
        serve.stop()
        ground, habitat = f.ground_chain(run_id), f.habitat.onboard_chain(run_id)
        assert len(ground) > stored  # caught up, and followed on
        assert [(e.seq, e.kind, e.hash) for e in ground] == [(e.seq, e.kind, e.hash) for e in habitat]
        assert verify_chain(run_id, ground).ok, verify_chain(run_id, ground).describe()
        # who attached and when, and the refusals, each under an id of its own
        log = AuditLog(f.db_url)
        try:
            records = attach_records(log, run_id)
        finally:
            log.close()
        assert [(kind, actor, data.get("rule")) for kind, actor, data in records] == [
            ("supervisor_attached", OPERATOR, None),
            ("action_refused", OPERATOR, "one_supervisor"),
            ("action_refused", "flight-3", "one_supervisor"),
        ], records
        supervisor = records[0][2]["supervisor"]
        assert records[0][2] == {"run": run_id, "supervisor": supervisor} and supervisor.endswith(f" for {OPERATOR}")
        assert f"{supervisor} holds it" in records[1][2]["reason"] and supervisor in records[2][2]["reason"]
        assert_flown_exactly_once(f, run_id, "completed", to=PICK_CLEAN_STEP)
