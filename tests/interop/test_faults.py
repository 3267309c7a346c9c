"""Faults on the real stack: a part dies mid-procedure, the run never pretends, nothing is lost.

Each test runs the IVA CDRA procedure on separate processes (simulation, planner, AT server,
rosbridge, runner with its JVM), kills one of them at a known point, and checks that the
procedure stops at that instruction with a reason, that the audit log holds every action up
to the fault, and how the run goes on once the part is back: a pull-out that fails goes to the
procedure's contingency step "removal_interrupted", which holds for the operator and then plans
the removal again from where the arm is (the restarted AT server keeps its instances). A pull-out
whose outcome is not known holds as unknown, and asking again with the same key gets the
habitat ledger's answer; it never moves the arm a second time.

A procedure is also taken up part way: a run that ended after the clean filter's pick leaves the
world at the insertion, and a run ``--from`` the insertion, given what lint says the skipped steps
would have bound, finishes the work as the deployment's world checks measure it.
"""

from __future__ import annotations

import re
import threading
from collections.abc import Iterator
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

import pytest

from caretaker.processes import REPO, VENV_BIN, caretaker
from caretaker.stack import Stack
from caretaker.world_checks import watch_world
from interop.terminal_session import TerminalSession
from pride.events import Event, EventKind
from pride.executive import Mode
from pride.replay import replay
from procedure_language.lint import check_procedure, section_needs
from procedure_language.sysrep import load_sysrep_dir
from records.audit_log import AuditLog
from sim.scene import load_scene
from support.second_operator import APPROVED_BY_BOB, approver_env
from support.stack import robot_parts

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=90)]

PROCEDURE = REPO / "procedures" / "iva_cdra_filter_replacement.xml"
BINDING = REPO / "sysrep" / "bindings" / "iva.yaml"
CLEAN_FILTER = "CDRA-F-0012"
# The manual instruction just before the arm moves in to pull the dirty filter.
CONFIRM_CLEAR = "2.6"
EXECUTE_PULL = "2.7"
# Step 9, removal_interrupted: the operator's check, then plan and execute the pull-out again.
CHECK_AFTER_INTERRUPTION = "9.1"
EXECUTE_PULL_AGAIN = "9.6"


class RobotSide:
    """The IVA deployment's parts, killed and started again by the test (caretaker.stack.Stack)."""

    def __init__(self, stack: Stack) -> None:
        self.stack = stack
        self.env = stack.env
        self.url = stack.bridge_url
        self.parts = stack.processes

    def start(self, name: str) -> None:
        self.stack.start_part(name)


@pytest.fixture
def robot(ros_env: dict[str, str]) -> Iterator[RobotSide]:
    with robot_parts("iva", ros_env) as stack:
        yield RobotSide(stack)


def _run_argv(robot: RobotSide, db: str, *extra: str) -> list[str]:
    return [
        str(VENV_BIN / "caretaker"),
        "run",
        "--binding",
        str(BINDING),
        "--rosbridge",
        robot.url,
        "--user",
        "ops",
        "--db",
        db,
        f"--set=clean_filter_id={CLEAN_FILTER}",
        "--rehearsal",
        *APPROVED_BY_BOB,  # the unlock, hazardous: bob approves it (the faults come after it)
        *extra,
    ]


class StatusWatch:
    """The AT server's status topic, seen through rosbridge like any ground-side client sees it."""

    def __init__(self, url: str) -> None:
        import roslibpy

        parsed = urlparse(url)
        self._ros = roslibpy.Ros(host=parsed.hostname, port=parsed.port)
        self._ros.run(30)
        self._changed = threading.Condition()
        self._messages: list[dict] = []
        self._topic = roslibpy.Topic(
            self._ros, "/affordance_template_server/status", "affordance_template_msgs/msg/ServerStatus"
        )
        self._topic.subscribe(self._take)

    def _take(self, message: dict) -> None:
        with self._changed:
            self._messages.append(message)
            self._changed.notify_all()

    def wait_for(self, execute_status: str, trajectory: str, timeout: float = 120.0) -> None:
        def seen() -> bool:
            return any(
                m["execute_status"] == execute_status and m["active_trajectory"] == trajectory for m in self._messages
            )

        with self._changed:
            if not self._changed.wait_for(seen, timeout):
                raise AssertionError(f"the AT server never reported {execute_status} for {trajectory!r}")

    def close(self) -> None:
        self._topic.unsubscribe()
        self._ros.close()


def _events(db: str, run_id: str) -> list:
    audit = AuditLog(db)
    try:
        return audit.events(run_id)
    finally:
        audit.close()


def _assert_log_is_whole(events: list) -> None:
    assert [e.seq for e in events] == list(range(events[0].seq, events[0].seq + len(events))), "sequence has gaps"
    assert events[0].kind is EventKind.RUN_STARTED


def _answer_until(session: TerminalSession, stop_at: str | None = None) -> str | None:
    """Answer manual holds with Enter until the run ends, or until a prompt at ``stop_at`` (returned)."""
    while True:
        match = session.expect(r"(?m)^\s*(\d+\.\d+)[^\n]*\n[^\n]*\[Enter\] done[^\n]*> |RESULT (\w+) run")
        if match.group(2):
            return match.group(2)
        if match.group(1) == stop_at:
            return None
        session.send("")


def test_rosbridge_killed_then_back(robot: RobotSide, tmp_path: Path) -> None:
    db = f"sqlite:///{tmp_path / 'audit.db'}"
    session = TerminalSession(_run_argv(robot, db, str(PROCEDURE), "--auto"), approver_env(db, robot.env))
    try:
        run_id = session.expect(r"READY run (\S+)").group(1)
        assert _answer_until(session, stop_at=CONFIRM_CLEAR) is None
        robot.parts["bridge"].kill()
        # the run knows the link is down before the operator goes on (a command written to a
        # connection as it drops is in flight, its outcome unknown: tests/flight covers that)
        session.expect(r"PAX\s+link lost since \S+, 0 commands in flight")
        session.send("")  # the area is clear: PAX sends the pull-out with no bridge to carry it
        assert _answer_until(session, stop_at=CHECK_AFTER_INTERRUPTION) is None
        # the command never reached the robot, and the reason says so
        _assert_pull_failed(_events(db, run_id), r"not connected")
        robot.start("bridge")
        session.expect(r"reconnected to ws://")  # the plugins' rosbridge client logs its reconnection
        session.send("")  # the bridge is back: the operator continues the contingency step
        assert _answer_until(session) == "completed"
        assert session.close() == 0
    finally:
        session.close(5)
    _assert_pulled_again_and_completed(_events(db, run_id))


def test_at_server_killed_during_execute(robot: RobotSide, tmp_path: Path) -> None:
    db = f"sqlite:///{tmp_path / 'audit.db'}"
    session = TerminalSession(_run_argv(robot, db, str(PROCEDURE), "--auto"), approver_env(db, robot.env))
    try:
        run_id = session.expect(r"READY run (\S+)").group(1)
        assert _answer_until(session, stop_at=CONFIRM_CLEAR) is None
        session.send("")
        session.expect(rf"{re.escape(EXECUTE_PULL)}\s+PAX\s+sent Execute Plan for cdra_filter:")
        robot.parts["at-server"].kill()
        # the call was on its way: whether the arm moved is not known, and the run says so
        session.expect(rf"{re.escape(EXECUTE_PULL)}\s+OUTCOME UNKNOWN: execute_plan")
        session.expect(r"\[n\] record: it failed[^\n]*> ")
        events = _events(db, run_id)
        assert not any(
            e.kind in (EventKind.INSTRUCTION_COMPLETED, EventKind.INSTRUCTION_FAILED) and e.instruction == EXECUTE_PULL
            for e in events
        ), "an unknown outcome was decided"
        session.send("n")  # the operator sees the arm stopped with the filter in: record it as failed
        session.expect(r"what did you check on the robot\? > ")
        session.send("camera: the filter is still in its slot")
        assert _answer_until(session, stop_at=CHECK_AFTER_INTERRUPTION) is None
        _assert_pull_failed(_events(db, run_id), r"recorded by ops: camera: the filter is still in its slot")
        robot.start("at-server")  # from its state file: cdra_filter and ready_pose with their ids
        robot.parts["at-server"].wait_for_line(r"restored cdra_filter:\d+, ready_pose:\d+ from ", 5)
        session.send("")  # the operator checked the arm: the removal is planned again
        assert _answer_until(session) == "completed"
        assert session.close() == 0
    finally:
        session.close(5)
    events = _events(db, run_id)
    sent = [e for e in events if e.kind is EventKind.COMMAND_SENT and e.instruction == EXECUTE_PULL]
    assert len(sent) == 1
    _assert_pulled_again_and_completed(events)


def _assert_pull_failed(events: list, reason: str) -> None:
    """The pull-out failed once, for ``reason`` (a regex), and nothing logged it as a success."""
    _assert_log_is_whole(events)
    assert not any(
        e.kind is EventKind.COMMAND_RESULT and e.instruction == EXECUTE_PULL and e.data.to_json().get("success")
        for e in events
    ), "a pull-out that did not finish was logged as a success"
    failed = [e for e in events if e.kind is EventKind.INSTRUCTION_FAILED and e.instruction == EXECUTE_PULL]
    assert len(failed) == 1 and re.search(reason, failed[0].data.to_json()["reason"]), failed


def _assert_pulled_again_and_completed(events: list) -> None:
    """The contingency step pulled the filter out after the operator's check, and the run went on to the end."""
    _assert_log_is_whole(events)
    assert not any(
        e.kind is EventKind.COMMAND_RESULT and e.instruction == EXECUTE_PULL and e.data.to_json().get("success")
        for e in events
    ), "the interrupted pull-out was logged as a success after all"
    numbers = [e.instruction for e in events if e.kind is EventKind.INSTRUCTION_COMPLETED]
    assert CHECK_AFTER_INTERRUPTION in numbers and "3.1" in numbers[numbers.index(CHECK_AFTER_INTERRUPTION) :]
    assert [
        e.actor
        for e in events
        if e.kind is EventKind.INSTRUCTION_COMPLETED and e.instruction == CHECK_AFTER_INTERRUPTION
    ] == ["ops"]
    assert any(
        e.kind is EventKind.COMMAND_RESULT and e.instruction == EXECUTE_PULL_AGAIN and e.data.to_json().get("success")
        for e in events
    )
    assert not any(e.kind is EventKind.RETRY for e in events)
    assert events[-1].kind is EventKind.RUN_COMPLETED


def test_runner_killed_during_execute_then_resumed(robot: RobotSide, tmp_path: Path) -> None:
    db = f"sqlite:///{tmp_path / 'audit.db'}"
    status = StatusWatch(robot.url)
    env = approver_env(db, robot.env)
    runner = caretaker(
        "run", *_run_argv(robot, db, str(PROCEDURE), "--auto", "--confirm-manual")[2:], env=env, name="runner"
    )
    try:
        run_id = runner.wait_ready(120).split()[2]
        status.wait_for("EXECUTING", "grasp_and_pull")  # the robot is pulling the filter out
        runner.kill()
        status.wait_for("SUCCEEDED", "grasp_and_pull")  # and finishes without the runner
    finally:
        runner.stop()
        status.close()
    before = _events(db, run_id)
    assert before, f"nothing logged for {run_id} in {db}; the runner printed:\n{runner.tail()}"
    _assert_log_is_whole(before)
    assert any(e.kind is EventKind.COMMAND_SENT and e.instruction == EXECUTE_PULL for e in before)
    assert not any(e.kind is EventKind.RUN_COMPLETED for e in before)
    # the command in flight is asked again with its key: the ledger answers its recorded outcome
    resumed = caretaker(
        "run", *_run_argv(robot, db, "--resume", run_id, "--confirm-manual")[2:], env=env, name="resumed"
    )
    try:
        resumed.proc.wait(timeout=300)
    finally:
        resumed.stop()
    assert resumed.proc.returncode == 0, resumed.tail()
    after = _events(db, run_id)
    _assert_log_is_whole(after)
    assert after[: len(before)] == before, "the resumed run changed what was already logged"
    sent = [e for e in after if e.kind is EventKind.COMMAND_SENT and e.instruction == EXECUTE_PULL]
    assert len(sent) == 2 and sent[0].data.to_json()["key"] == sent[1].data.to_json()["key"], (
        "asked again under a new key"
    )
    answers = [e for e in after if e.kind is EventKind.COMMAND_RESULT and e.instruction == EXECUTE_PULL]
    assert len(answers) == 1 and answers[0].data.to_json()["success"], answers
    # the habitat's ledger answered the key from its record: the arm did not pull a second time
    robot.parts["ledger"].wait_for_line(
        rf"{re.escape(sent[1].data.to_json()['key'])}: re-sent: answered from the record", 5
    )
    assert after[-1].kind is EventKind.RUN_COMPLETED


def test_the_filter_slipping_out_during_the_pull_out_halts_the_arm_and_goes_to_the_contingency(
    robot: RobotSide, tmp_path: Path
) -> None:
    """The procedure's monitor on the gripper (its grasp never ``empty`` while the filter is taken
    out): the simulator's test service lets the held filter slip out as soon as it is held; PAX
    halts what is in progress (the pull-out, or the check after it if the 1.3 s pull ended first),
    records the violation with the value, and goes to step ``filter_slipped``: nothing is placed."""
    import roslibpy

    db = f"sqlite:///{tmp_path / 'audit.db'}"
    parsed = urlparse(robot.url)
    ros = roslibpy.Ros(host=parsed.hostname, port=parsed.port)
    ros.run(30)
    grasps: list[str] = []
    holding = threading.Event()

    def took(message: dict) -> None:
        grasps.append(message["data"])
        if message["data"] == "holding":
            holding.set()

    grasp = roslibpy.Topic(ros, "/gripper/grasp", "std_msgs/msg/String")
    grasp.subscribe(took)
    moving: list[bool] = []
    moved = threading.Condition()

    def saw_motion(message: dict) -> None:
        with moved:
            moving.append(message["data"])
            moved.notify_all()

    motion = roslibpy.Topic(ros, "/robot/moving", "std_msgs/msg/Bool")
    motion.subscribe(saw_motion)
    session = TerminalSession(_run_argv(robot, db, str(PROCEDURE), "--auto"), approver_env(db, robot.env))
    try:
        run_id = session.expect(r"READY run (\S+)").group(1)
        assert _answer_until(session, stop_at=CONFIRM_CLEAR) is None
        session.send("")  # the area is clear: the arm moves in, grasps the filter and pulls
        assert holding.wait(120), f"the gripper never held the filter: {grasps}"
        slipped = roslibpy.Service(ros, "/sim/check/slip", "std_srvs/srv/Trigger").call(
            roslibpy.ServiceRequest({}), timeout=30
        )
        assert slipped["success"], slipped
        session.expect(
            r"monitor violated: gripper\.grasp = empty \(must be ≠ empty\): HALT, then go to step filter_slipped"
        )
        session.expect(r"went to 10\.1")
        with moved:  # the arm at rest (halted mid-motion, or already still when the slip was seen)
            assert moved.wait_for(lambda: moving and moving[-1] is False, 60), moving
        session.expect(r"10\.1[^\n]*\n[^\n]*\[Enter\] done")  # the contingency holds for the operator
    finally:
        session.close(5)
        grasp.unsubscribe()
        motion.unsubscribe()
        ros.close()
    events = _events(db, run_id)
    _assert_log_is_whole(events)
    # seen during the pull-out, or just after it (the 1.3 s pull may end first): steps 2 and 3 watch
    (violated,) = [e for e in events if e.kind is EventKind.MONITOR_VIOLATED]
    assert violated.data.to_json()["value"] == "empty" and (violated.instruction or "")[:2] in ("2.", "3."), violated
    (went,) = [e for e in events if e.kind is EventKind.WENT_TO]
    assert went.data.to_json()["from"][:2] in ("2.", "3.") and went.data.to_json()["next"] == "10.1", went
    placed = [
        e
        for e in events
        if e.kind is EventKind.COMMAND_SENT and e.data.to_json()["command"] == "execute_plan" and e.seq > violated.seq
    ]
    assert not placed, placed  # no motion after the violation: the filter was never carried to the rack
    awaiting = [e.instruction for e in events if e.kind is EventKind.AWAITING_OPERATOR]
    assert awaiting[-1] == "10.1", awaiting  # the contingency's check, for the operator


def test_a_run_from_the_insertion_on_a_world_left_there_completes_and_its_report_says_where_it_started(
    robot: RobotSide, tmp_path: Path
) -> None:
    """The world is brought to the insertion by the procedure itself: a run ``--to pick_clean``
    (the spent filter on the rack, the clean one in the gripper where its pick ended, the templates
    on the AT server: a completed run takes nothing back). A second run ``--from insert_clean``
    gets, with ``--set``, what :func:`section_needs` lists, read from the first run's record; it
    completes, the deployment's world checks that the insertion's part of them failed before now
    hold, and its report says where it started."""
    db = f"sqlite:///{tmp_path / 'audit.db'}"
    checked = check_procedure(PROCEDURE, load_sysrep_dir(REPO / "sysrep"))
    steps = {step.id: step for step in checked.procedure.steps}
    insertion = steps["insert_clean"]
    deployment = robot.stack.deployment
    assert deployment.demo is not None and deployment.demo.inputs == {"clean_filter_id": CLEAN_FILTER}
    with watch_world(deployment.demo.checks, robot.url, deployment.namespace, load_scene(deployment.scene)) as world:
        env = approver_env(db, robot.env)
        prepared = _run_to_end(robot, db, env, str(PROCEDURE), "--to", "pick_clean")
        events = _events(db, prepared)
        assert events[-1].kind is EventKind.RUN_COMPLETED
        assert not [e for e in events if e.kind is EventKind.INSTRUCTION_STARTED and _step_of(e) >= insertion.number]
        before = [v.holds for v in world.judge(db, prepared)]
        assert before == [True, False, False], before  # the dirty filter on the rack; the cabinet empty
        held = replay(checked.procedure, events, checked.load, mode=Mode.AUTONOMOUS, statuses={}).frames[0].env
        needs = [u.name for u in section_needs(checked, insertion.id)]
        assert needs, "lint says the insertion reads nothing the steps before it bind"
        given = [f"--set={name}={_value(held, name)}" for name in needs]
        run_id = _run_to_end(robot, db, env, str(PROCEDURE), "--from", insertion.id, *given)
        verdicts = world.judge(db, run_id)
    assert all(v.holds for v in verdicts), [v.words for v in verdicts]
    events = _events(db, run_id)
    _assert_log_is_whole(events)
    assert events[0].data.to_json()["section"]["from"] == insertion.id
    started = {_step_of(e) for e in events if e.kind is EventKind.INSTRUCTION_STARTED}
    assert min(started) == insertion.number, started
    assert events[-1].kind is EventKind.RUN_COMPLETED
    report = caretaker("report", run_id, "--db", db, "--out", str(tmp_path / "reports"), env=robot.env, name="report")
    try:
        assert report.proc.wait(timeout=120) == 0, report.tail()
    finally:
        report.stop()
    markdown = (tmp_path / "reports" / f"{run_id}.md").read_text()
    where = f"- Part of the procedure: started at step {insertion.number} ({insertion.title}); given for the steps"
    assert f"{where} before: " in markdown, markdown[:2000]


def _run_to_end(robot: RobotSide, db: str, env: dict[str, str], *extra: str) -> str:
    """``caretaker run`` unattended to its end (it must complete); its run id."""
    runner = caretaker("run", *_run_argv(robot, db, "--auto", "--confirm-manual", *extra)[2:], env=env, name="runner")
    try:
        words = runner.wait_for_line(r"^RESULT ", 600).split()
        assert runner.proc.wait(timeout=60) == 0, runner.tail()
    finally:
        runner.stop()
    assert words[1] == "completed", runner.tail()
    return words[3]


def _step_of(event: Event) -> int:
    """The step number of an event's instruction (``5`` of ``5.2``)."""
    return int((event.instruction or "0").split(".")[0])


def _value(variables: dict[str, Any], name: str) -> Any:
    """A variable's value as ``--set`` names it: ``name``, or ``result.field`` of a command's result."""
    base, _, field = name.partition(".")
    return variables[base][field] if field else variables[base]
