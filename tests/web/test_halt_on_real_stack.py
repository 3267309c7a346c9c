"""HALT from the console stops the real arm, measured on the robot side; after it, the operator's
way on completes the run.

``caretaker up iva`` (simulation, planner, AT server, ledger, rosbridge) and ``caretaker serve``
with the JVM PAX plugins. PAX runs the IVA procedure autonomously, the simulator flat out; the
operator sends the unlock for approval (bob approves it) and, at the confirmation that the area is
clear (2.6), the test slows the simulator to a tenth of real time (real time when
``CARETAKER_HALT_TIME_SCALE=1``, as bench/halt_under_load.py runs it: the simulator's
``time_scale`` parameter). While the arm pulls the dirty filter out (2.7) the operator presses
HALT. The arm's ``/joint_states``, read over the stack's rosbridge with their sim-time stamps,
come to rest and stay there; the instruction is recorded as halted by the operator, never as
completed. A second run on the robot is then refused, naming the run that controls it.

It also reports the wall-clock time from the press to the arm at rest (HALT acts on the press, not
on the release): from the pointerdown event in the page (its timestamp) until the first joint
state of the resting arm reached this test (so it includes the delivery of that state over the
bridge). bench/halt_under_load.py runs this test repeatedly beside CPU hogs and collects that
figure (docs/benchmarks.md); it is printed, not asserted.

After a Halt mid-motion the plan of the pull-out has ended with it: the banner offers to re-plan
from where the arm is and go on (no retry or continue of the halted motion, which cannot work);
that goes back to the plan instruction, the AT server plans the rest of the pull-out from where
the arm stopped, and the run completes. No text the operator sees names an AT server service.
One robot stack serves both halves: the halt, then the way on from it.
"""

from __future__ import annotations

import json
import os
import re
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
import roslibpy
from playwright.sync_api import Locator, Page, expect

from pride.events import EventKind
from records.audit_log import AuditLog
from support.operator_page import (
    IVA,
    audit_row,
    expect_current,
    expect_ended,
    instruction,
    start_run,
    unlock_approved_by,
)
from support.sim_pace import set_sim_time_scale
from support.stack import stack_up
from support.web_server import REPO, WebServer, start_server

pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.timeout(900)]

PULL_OUT = "2.7"
PLAN_PULL_OUT = "2.2"
#: PAX plans and moves the real arm on the way to a hold.
MOTION_MS = 180_000
#: The AT server's service names: an operator meets the SysRep's commands, never these.
SERVICE_NAMES = ("plan_command", "execute_command")


class RobotSide:
    """The habitat's own account, over its rosbridge: joint states and the AT server's status."""

    def __init__(self, url: str) -> None:
        host, port = url.split("//")[1].rsplit(":", 1)
        self.ros = roslibpy.Ros(host, int(port))
        self.ros.run(timeout=30)
        self.changed = threading.Condition()
        self.samples: list[tuple[float, tuple[float, ...]]] = []
        self.received: list[float] = []  # time.time() each sample arrived here
        roslibpy.Topic(self.ros, "/joint_states", "sensor_msgs/msg/JointState").subscribe(self._on_joints)

    def _on_joints(self, msg: dict[str, Any]) -> None:
        stamp = msg["header"]["stamp"]
        with self.changed:
            self.samples.append((stamp["sec"] + stamp["nanosec"] * 1e-9, tuple(msg["position"])))
            self.received.append(time.time())
            self.changed.notify_all()

    def wait(self, condition: Any, what: str, timeout: float = 120.0) -> None:
        with self.changed:
            if not self.changed.wait_for(condition, timeout):
                raise AssertionError(f"the robot side never showed {what}")

    def latest_stamp(self) -> float:
        with self.changed:
            return self.samples[-1][0]

    def at(self, moment: float) -> tuple[float, bool]:
        """The stamp of the last sample that arrived before ``moment`` (time.time()), and whether
        the arm was moving then (it differs from the sample before it)."""
        with self.changed:
            before = [s for s, r in zip(self.samples, self.received, strict=True) if r < moment]
        return before[-1][0], len(before) >= 2 and before[-1][1] != before[-2][1]

    def still_since(self, moment: float) -> tuple[float, float]:
        """Among the samples that arrived after ``moment`` (time.time()): the stamp from which the
        joints never changed again, and when the first sample of that rest arrived here."""
        with self.changed:
            later = [(s, r) for s, r in zip(self.samples, self.received, strict=True) if r >= moment]
        rest = later[-1][0][1]
        still, arrived = later[-1][0][0], later[-1][1]
        for (stamp, positions), received in reversed(later):
            if positions != rest:
                break
            still, arrived = stamp, received
        return still, arrived

    def close(self) -> None:
        self.ros.close()


#: The pull-out's time scale: a tenth of real time in the suite, so that a press while it moves
#: reaches the robot before it ends on a starved machine (at real time its 4 s were twice over
#: first, at a quarter its 16 s once, at a load of 40); bench/halt_under_load.py sets 1, as the
#: halt's timing is measured. The halt ends the slow motion early; the rest of the run goes as fast
#: as the simulator can.
HALT_TIME_SCALE = float(os.environ.get("CARETAKER_HALT_TIME_SCALE", "0.1"))


@pytest.fixture
def iva_and_console(tmp_path: Path, ros_env: dict[str, str]) -> Iterator[tuple[WebServer, RobotSide]]:
    """The IVA robot side flat out (its pace set per motion by :func:`set_sim_time_scale`)
    and ``caretaker serve`` on it."""
    with stack_up("iva", ros_env) as stack:
        server = start_server(tmp_path, REPO / "procedures", rosbridge=[stack.url])
        robot = RobotSide(stack.url)
        try:
            yield server, robot
        finally:
            robot.close()
            server.process.stop()


def _at_the_confirmation(open_page: Callable[[WebServer, str], Page], server: WebServer) -> tuple[Page, str, Locator]:
    """alice starts the IVA procedure autonomously; once PAX holds at the confirmation that the area
    in front of the cabinet is clear (2.6, before the pull-out): her page, the run's id, that instruction."""
    alice = open_page(server, "alice")
    run_id = start_run(alice, IVA, "autonomous")
    unlock_approved_by(alice, "bob", timeout=240_000)  # hazardous in the cdra SysRep: bob approves it
    confirm = instruction(alice, "2.6")
    expect_current(confirm, timeout=240_000)
    return alice, run_id, confirm


def _pull_out_halted(alice: Page, confirm: Locator) -> Locator:
    """alice confirms the area is clear, then halts the pull-out in flight; returns the pull-out.

    The press comes as soon as her page shows the pull-out executing, not once the robot side's
    samples show the arm moving: under the suite's load those came so late that the press reached
    the robot after the pull-out's end. The halt then stops the motion early in its 40 s (at a
    tenth of real time), or cancels the goal before it moves: either way it is halted."""
    confirm.locator("button.done").click()
    alice.wait_for_function(f"view.state && view.state.current === '{PULL_OUT}' && view.state.executing")
    alice.click("#halt")
    pull = instruction(alice, PULL_OUT)
    expect(pull).to_have_attribute("data-status", "halted")
    return pull


def test_halt_during_the_pull_out_stops_the_arm_then_re_planning_from_where_it_is_completes_the_run(
    open_page: Callable[[WebServer, str], Page], iva_and_console: tuple[WebServer, RobotSide]
) -> None:
    server, robot = iva_and_console
    alice, run_id, confirm = _at_the_confirmation(open_page, server)
    set_sim_time_scale(HALT_TIME_SCALE)  # the pull-out slowed down, so that the press reaches it moving
    # Ready beforehand: the press is all that is left to do once the pull-out executes.
    alice.fill("#halt-reason", "crew member at the cabinet")
    # what the button says after the press, in order: the press is acknowledged before any answer
    alice.evaluate("""() => {
      const button = document.getElementById("halt");
      window.haltSaid = [];
      // the first frame drawn after the button changed: when the operator can see "halting…"
      new MutationObserver(() => {
        window.haltSaid.push(button.textContent);
        if (window.haltDrawnAt === undefined) {
          window.haltDrawnAt = null;
          requestAnimationFrame(() => requestAnimationFrame(() => { window.haltDrawnAt = performance.now(); }));
        }
      }).observe(button, {childList: true, characterData: true, subtree: true});
      // when the browser painted the press's effect: its event timing (the next paint after the
      // handlers ran, to 8 ms; reported only for 16 ms or more: none means sooner)
      window.haltPainted = [];
      new PerformanceObserver((list) => {
        for (const entry of list.getEntries()) {
          if (entry.name === "pointerdown" && entry.target === button) {
            window.haltPainted.push({painted: entry.duration, handled: entry.processingStart - entry.startTime});
          }
        }
      }).observe({type: "event", durationThreshold: 16});
      // the press: HALT acts on it (the release comes later)
      button.addEventListener("pointerdown",
                              (event) => { window.haltClickedAt = performance.timeOrigin + event.timeStamp; },
                              {capture: true});
    }""")
    pull = _pull_out_halted(alice, confirm)
    clicked = alice.evaluate("window.haltClickedAt") / 1000  # the page's clock is this machine's
    pressed_after = robot.latest_stamp()
    robot.wait(lambda: robot.samples[-1][0] >= pressed_after + 3.0, "3 s of sim time after the halt", timeout=240)
    alice.wait_for_function("window.haltDrawnAt !== null")
    shown = alice.evaluate("performance.timeOrigin + window.haltDrawnAt") / 1000
    painted = alice.evaluate("window.haltPainted")
    # figures, not assertions: the suite's load stretches any wall-clock time (bench/halt_under_load.py)
    timing = painted[0] if painted else None
    said = (
        f"painted {timing['painted'] / 1000:.3f} s after the press (handled after {timing['handled'] / 1000:.3f} s"
        if timing
        else "painted <0.016 s after the press (the browser reports 16 ms or more"
    )
    print(f"HALT: 'halting…' {said}; the second frame after the change began {shown - clicked:.3f} s after the press)")
    assert shown >= clicked
    pressed, moving = robot.at(clicked)
    still, arrived = robot.still_since(clicked)
    stopped_after = still - pressed
    # at rest, and staying there: the 3 s of sim time after the press end with it standing still
    resting = robot.latest_stamp() - still
    assert resting >= 1.0, f"the arm still moved {resting:.2f} s of sim time before the end"
    if moving:
        print(
            f"HALT: the arm at rest {arrived - clicked:.3f} s wall-clock after the press "
            f"({stopped_after:.3f} s of sim time after the press)"
        )
        # Printed, not asserted: the 0.5 s is wall-clock beside two CPU hogs, measured ten
        # times by bench/halt_under_load.py. The sim-time figure counts from the last state that
        # reached this test before the press, which a loaded machine delivers late (0.65 s here
        # with the arm at rest 0.36 s wall-clock after the press, on a quiet machine).
    else:
        # A press before the goal moved, or between two segments: the next segment does not start
        # (at_ros.halt), so there is no motion to time (bench/halt_under_load.py counts such tries apart).
        print("HALT: the arm was still at the press (between two segments of the pull-out): no figure")

    expect(alice.locator("#halt")).to_have_text("HALT")  # once the console has answered
    assert alice.evaluate("window.haltSaid") == ["halting…", "HALT"]
    expect(pull.locator(".mark")).to_contain_text("halted by alice")
    expect(audit_row(alice, "halt", PULL_OUT, "alice")).to_contain_text("HALT: crew member at the cabinet")
    log = AuditLog(server.database.url)
    try:
        events = [e for e in log.events(run_id) if e.instruction == PULL_OUT]
    finally:
        log.close()
    recorded = next(e.time.timestamp() for e in events if e.kind is EventKind.HALT)
    if moving and float(HALT_TIME_SCALE) == 1.0:  # where the time went (sim stamps follow the wall clock)
        print(
            f"HALT timeline after the press: console recorded it {recorded - clicked:+.3f} s, "
            f"arm at rest (sim stamp) {still - clicked:+.3f} s, that state arrived here {arrived - clicked:+.3f} s"
        )
    assert [e.actor for e in events if e.kind is EventKind.INSTRUCTION_HALTED] == ["alice"], events
    assert not [e for e in events if e.kind is EventKind.INSTRUCTION_COMPLETED], "a halted pull-out logged as completed"
    set_sim_time_scale(0)  # the rest as fast as the simulator can

    # a second run on the robot is refused, naming alice's run (taking over: test_flight_controls.py)
    bob = open_page(server, "bob")
    bob.select_option("#start-procedure", IVA)
    bob.select_option("#start-binding", "iva.yaml")
    bob.check("#start-rehearsal")
    bob.click("#start-button")
    expect(bob.locator("#start-error")).to_contain_text(f"controlled by run {run_id} (user alice")

    # the banner offers what can work, in the operator's words; not the retry or continue of the
    # halted pull-out, whose plan ended with the halt
    hold = alice.locator("#hold")
    replan = alice.locator("#replan")
    expect(replan).to_be_visible()
    expect(replan).to_have_text("Re-plan from where the arm is and go on")
    expect(hold).to_contain_text(
        "its plan ended with the halt: an operator may re-plan from where the arm is and go on "
        f"(from {PLAN_PULL_OUT}), go back to an earlier instruction, skip it or stop the run"
    )
    expect(hold).to_contain_text("by alice: crew member at the cabinet")
    expect(hold).not_to_contain_text(re.compile("retry|continue", re.IGNORECASE))
    expect(pull.locator("button.retry")).to_be_hidden()
    expect(alice.locator("#continue")).to_be_disabled()
    expect(pull.locator("button.skip")).to_be_visible()
    expect(instruction(alice, PLAN_PULL_OUT).locator("button.go-back")).to_be_visible()
    # forced through the API, the executive refuses them and says what can work
    token = {"X-CSRF-Token": alice.evaluate("view.me.csrf")}
    for action in ("retry", "continue"):
        refused = alice.request.post(
            f"{server.url}/api/runs/{run_id}/actions", headers=token, data={"action": action, "instruction": PULL_OUT}
        )
        assert refused.status == 409, refused.text()
        assert refused.json()["error"] == (
            f"{PULL_OUT} cannot be sent again: the plan of grasp_and_pull of cdra_filter:0 ended with the halt; "
            f"re-plan from where the arm is ({PLAN_PULL_OUT}) and go on"
        )

    # re-planned: back to the plan, recorded as alice's; PAX plans the rest of the pull-out from
    # where the arm stopped, and holds for the confirmation that the area is clear again
    replan.click()
    expect(audit_row(alice, "stepped_back", PULL_OUT, "alice")).to_contain_text(
        f"went back to {PLAN_PULL_OUT}: re-plan grasp_and_pull of cdra_filter:0 from where the arm is and go on"
    )
    expect(replan).to_be_hidden()
    unlock_approved_by(alice, "bob", timeout=MOTION_MS)  # the unlock again: each sending is approved
    expect_current(confirm, timeout=MOTION_MS)
    expect(audit_row(alice, "command_result", PLAN_PULL_OUT, "PAX").first).to_contain_text("succeeded")
    confirm.locator("button.done").click()
    record = instruction(alice, "4.1")
    expect_current(record, timeout=MOTION_MS)
    expect(pull.locator(".mark")).to_contain_text("completed by PAX")
    record.locator("input.record-value").fill("CDRA-F-0012")
    record.locator("button.record").click()
    slot_clear = instruction(alice, "5.1")
    expect_current(slot_clear, timeout=MOTION_MS)
    slot_clear.locator("button.done").click()
    expect_ended(alice, "completed", within_ms=MOTION_MS)

    # nothing the operator sees, on the page or in the run's report, names an AT server service
    page_text = alice.evaluate("document.body.textContent")
    report = alice.request.get(f"{server.url}/runs/{run_id}/report")
    assert report.ok, report.status
    log = AuditLog(server.database.url)
    try:
        events = log.events(run_id)
    finally:
        log.close()
    for name in SERVICE_NAMES:
        assert name not in page_text and name not in report.text()
        assert not [e for e in events if name in json.dumps(e.data.to_json())], name
    back = [e for e in events if e.kind is EventKind.STEPPED_BACK]
    assert [(e.actor, e.instruction, e.data.to_json()["next"]) for e in back] == [("alice", PULL_OUT, PLAN_PULL_OUT)]
    pulls = [e for e in events if e.kind is EventKind.COMMAND_RESULT and e.instruction == PULL_OUT]
    assert [e.data.to_json()["outcome"] for e in pulls] == ["halted", "succeeded"], pulls
