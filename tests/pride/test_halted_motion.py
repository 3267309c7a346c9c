"""After a halted motion: retry and continue cannot work, re-planning from where the arm is can.

The gateway is a motion system in a dict (:class:`PlanOnce`): a plan is stored per template
instance and used up by its execution, and an execution refuses without one, as the AT server
does; an execution may be held moving until a halt cancels it. The real stack's version, in the
browser, is tests/web/test_halt_on_real_stack.py; the AT server's texts in an operator's words
are checked at the end.
"""

from __future__ import annotations

import io
import threading
from collections.abc import Mapping
from typing import Any

import pytest

from caretaker.terminal import OperatorConsole, TerminalLines, Unattended
from pride.at_words import operator_words
from pride.events import EventKind
from pride.executive import Executive, Hold, InstructionStatus, OperatorActionError, RunStatus
from pride.systems import CancelResult, CommandResult, LinkListener, Outcome, TelemetryListener, TelemetryValue
from support.audit import RecordedJournal
from support.executive_runs import TIMEOUT, Bench, finished, held

PROCEDURE = "at_halted_motion.xml"  # 1.x add; 2.1 plans the pull, 2.2 the stow, 2.3 manual, 2.4 pulls; 3.1 stows
PULL = "2.4 cannot be sent again: the plan of grasp_and_pull of cdra_filter:0 ended with the halt"


class PlanOnce:
    """The AT SysRep's commands as a motion system keeps them: one stored plan per instance, used up
    by its execution; ``moving`` holds executions of those trajectories until a cancel halts them."""

    def __init__(self) -> None:
        self.plans: dict[str, str] = {}  # instance -> the trajectory planned for it
        self.added: dict[str, int] = {}  # template -> instances added (ids from 0, as the AT server's)
        self.moving: set[str] = set()  # trajectories whose execution moves until halted
        self.started = threading.Event()  # such an execution is moving now
        self.executed: list[str] = []  # trajectories executed to the end, in order
        self._halt = threading.Event()

    def execute(self, sysrep_id: str, command_id: str, args: Mapping[str, Any], *, key: str | None = None) -> Any:
        instance, trajectory = str(args["affordance_template"]), str(args.get("trajectory"))
        if command_id == "add_affordance_template":
            number = self.added[instance] = self.added.get(instance, -1) + 1
            name = f"{instance}:{number}"
            return CommandResult(Outcome.SUCCEEDED, f"added {name}", {"id": number, "instance": name})
        if command_id == "plan_trajectory":
            self.plans[instance] = trajectory
            return CommandResult(Outcome.SUCCEEDED, f"planned {trajectory}", {"plan_valid": True})
        if command_id == "execute_plan":
            if self.plans.pop(instance, None) != trajectory:
                return CommandResult(Outcome.FAILED, f"no valid plan for {trajectory!r} of {instance}")
            if trajectory in self.moving:
                self._halt.clear()
                self.started.set()
                self._halt.wait()
                self.started.clear()
                return CommandResult(Outcome.HALTED, f"halted during {trajectory} of {instance}")
            self.executed.append(trajectory)
            return CommandResult(Outcome.SUCCEEDED, f"executed {trajectory}")
        return CommandResult(Outcome.SUCCEEDED, f"deleted {instance}")  # a stop takes back what a run added

    def cancel(self, key: str) -> CancelResult:
        self._halt.set()
        return CancelResult(True, "stopped where it was")

    def system_ids(self) -> frozenset[str]:
        return frozenset({"affordance_templates"})

    def robot(self) -> str:
        return "bench"

    def one_way_delay(self) -> float:
        return 0.0

    def telemetry(self, sysrep_id: str, item_id: str) -> TelemetryValue:
        raise KeyError(item_id)  # the procedure reads none

    def add_listener(self, callback: TelemetryListener) -> None:
        pass

    def add_link_listener(self, callback: LinkListener) -> None:
        pass

    def close(self) -> None:
        pass


def _halted_mid_motion(bench: Bench, trajectory: str, number: str) -> tuple[Executive, PlanOnce, RecordedJournal]:
    """A run in which alice confirms the area is clear (2.3) and bob halts ``trajectory`` mid-motion at ``number``."""
    motion = PlanOnce()
    motion.moving.add(trajectory)
    executive, _, journal = bench(name=PROCEDURE, gateway=motion)
    executive.start("alice")
    held(executive, Hold.OPERATOR_ACTION, "2.3")
    executive.mark_done("alice")
    assert motion.started.wait(TIMEOUT), f"{number} never moved"
    executive.halt("bob", "crew member at the cabinet")
    snap = held(executive, Hold.HALTED, number)
    assert snap.statuses[number] is InstructionStatus.HALTED
    return executive, motion, journal


def test_after_a_halted_motion_re_planning_goes_back_to_its_plan_and_the_run_goes_on(bench: Bench) -> None:
    executive, motion, journal = _halted_mid_motion(bench, "grasp_and_pull", "2.4")

    # the plan of the pull ended with the halt: the way on is its plan instruction, 2.1 (not 2.2,
    # which plans another motion), and neither a retry nor continue is offered or accepted
    snap = executive.snapshot()
    assert snap.replan_from == "2.1"
    assert snap.no_retry == f"{PULL}; re-plan from where the arm is (2.1) and go on"
    assert snap.to_json()["replan_from"] == "2.1" and snap.to_json()["no_retry"] == snap.no_retry
    for refused in (executive.retry, executive.resume_automation):
        with pytest.raises(OperatorActionError, match=f"^{PULL}; re-plan from where the arm is"):
            refused("bob")
    with pytest.raises(OperatorActionError, match=f"halted by bob: crew member at the cabinet: {PULL}"):
        executive.perform("bob")

    executive.replan("bob")
    # PAX plans the pull again (a new attempt), and holds again for the operator's confirmation
    held(executive, Hold.OPERATOR_ACTION, "2.3")
    (back,) = [e for e in journal.events if e.kind is EventKind.STEPPED_BACK]
    assert (back.actor, back.instruction, back.data.to_json()["next"], back.data.to_json()["reset"]) == (
        "bob",
        "2.4",
        "2.1",
        ["2.1", "2.2", "2.3", "2.4"],
    )
    assert (
        back.data.to_json()["reason"]
        == "re-plan grasp_and_pull of cdra_filter:0 from where the arm is and go on (2.4 was halted)"
    )
    assert back.time is not None  # who, when and why, as every action
    plans = [
        e.data.to_json()["key"] for e in journal.events if e.kind is EventKind.COMMAND_SENT and e.instruction == "2.1"
    ]
    assert plans == ["run-1/2.1/1", "run-1/2.1/2"]
    assert executive.snapshot().no_retry == ""  # the halted motion is behind the run now
    motion.moving.clear()
    executive.mark_done("bob")
    assert finished(executive).status is RunStatus.COMPLETED
    assert motion.executed == ["grasp_and_pull", "ready"]


def test_a_halted_motion_planned_in_another_step_offers_no_re_plan_and_no_retry(bench: Bench) -> None:
    executive, _, journal = _halted_mid_motion(bench, "ready", "3.1")

    stow = "3.1 cannot be sent again: the plan of ready of ready_pose:0 ended with the halt"
    snap = executive.snapshot()
    assert snap.replan_from is None
    assert snap.no_retry == f"{stow}; go back to an instruction that plans it, skip it or stop the run"
    for refused in (executive.retry, executive.resume_automation, executive.replan):
        with pytest.raises(OperatorActionError, match=f"^{stow}; go back"):
            refused("bob")
    executive.skip("bob", "the arm is stowed by hand")
    assert finished(executive).status is RunStatus.COMPLETED
    assert not [e for e in journal.events if e.kind is EventKind.STEPPED_BACK]


def test_a_halted_plan_is_retried_as_a_new_attempt_and_re_planning_is_no_action_then(bench: Bench) -> None:
    motion = PlanOnce()
    executive, _, journal = bench(name=PROCEDURE, gateway=motion)
    executive.start("alice")
    held(executive, Hold.OPERATOR_ACTION, "2.3")
    executive.halt("bob", "wait")  # nothing moves: the run holds at the manual instruction
    snap = held(executive, Hold.HALTED, "2.3")
    assert (snap.replan_from, snap.no_retry) == (None, "")
    with pytest.raises(OperatorActionError, match="2.3 is no halted motion to plan again"):
        executive.replan("bob")
    executive.resume_automation("bob")
    held(executive, Hold.OPERATOR_ACTION, "2.3")


@pytest.mark.parametrize(
    ("said", "meant"),
    [
        (
            "no valid plan for 'ready' of ready_pose:0; call plan_command first",
            "ready of ready_pose:0 has no valid plan now (the arm was halted or moved): re-plan it first",
        ),
        (
            "cdra_filter:0 has no plan of 'grasp_and_pull' yet; call plan_command first",
            "cdra_filter:0 has no plan of grasp_and_pull yet: plan it first",
        ),
        ("ready_pose:2 has no plan yet; call plan_command first", "ready_pose:2 has no plan yet: plan it first"),
        (
            "link lost 12 s, /arm2/affordance_template_server/execute_command not answered",
            "link lost 12 s, the AT server's execution service not answered",
        ),
        (
            "plan_trajectory: the reply of /affordance_template_server/plan_command has no 'success' field",
            "plan_trajectory: the reply of the AT server's planning service has no 'success' field",
        ),
        # the procedure's own words stay: SysRep commands, halt, a planning failure
        ("set_waypoint_pose refused while halted", "set_waypoint_pose refused while halted"),
        (
            "planning 'grasp_and_pull' of cdra_filter:0 failed: out of reach",
            "planning 'grasp_and_pull' of cdra_filter:0 failed: out of reach",
        ),
    ],
)
def test_the_at_servers_texts_reach_an_operator_in_words_without_service_names(said: str, meant: str) -> None:
    assert operator_words(said) == meant


def test_the_terminal_offers_re_planning_at_a_halted_motion_and_no_retry(bench: Bench) -> None:
    executive, motion, journal = _halted_mid_motion(bench, "grasp_and_pull", "2.4")
    out = io.StringIO()
    prompts: list[str] = []
    answers = iter(["p", "q", "done here"])

    def read(prompt: str) -> str:  # re-plan; then, back at 2.3's confirmation, stop: the test is over
        prompts.append(prompt)
        return next(answers)

    console = OperatorConsole(executive, "bob", Unattended(), interactive=True, out=TerminalLines(out), read=read)
    assert console.run().status is RunStatus.STOPPED
    assert "[p] re-plan from where the arm is and go on (from 2.1)" in prompts[0]
    assert "retry" not in prompts[0].split("\n", 1)[1]  # neither retry nor continue is offered
    assert f"{PULL}; re-plan from where the arm is (2.1) and go on" in out.getvalue()
    (back,) = [e for e in journal.events if e.kind is EventKind.STEPPED_BACK]
    assert (back.actor, back.data.to_json()["next"]) == ("bob", "2.1")
