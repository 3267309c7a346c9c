"""PAX executive: every instruction kind, both modes, breakpoints, pause/stop, retry/skip, branching.

The gateway is the lab bench double (a unit test of the executive alone); the end-to-end runs
against a killable runner process are in test_runner.py.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path

import pytest

from pride.events import PAX, Event, EventKind
from pride.executive import Executive, Hold, InstructionStatus, Mode, OperatorActionError, RunStatus
from procedure_language.diagnostics import ProcedureError
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from support.audit import RecordedJournal
from support.executive_runs import TIMEOUT, Bench, finished, held
from support.lab_gateway import LabGateway
from support.procedures import FIXTURES


def test_autonomous_run_performs_every_kind_and_holds_only_for_the_operator(bench: Bench) -> None:
    executive, gateway, journal = bench()
    executive.start("alice")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    assert gateway.sent == []
    assert executive.enter("alice", "dock") == "dock"
    held(executive, Hold.CONFIRMATION, "2.1")
    assert [c for _, c, _ in gateway.sent] == ["move"]
    executive.confirm("bob")
    held(executive, Hold.OPERATOR_ACTION, "2.4")
    executive.mark_done("bob")
    snap = finished(executive)

    assert snap.status is RunStatus.COMPLETED
    assert [(c, a) for _, c, a in gateway.sent] == [
        ("move", {"target": "dock", "speed": 0.5}),
        ("vent", {}),
        ("capture", {"label": "dock_view"}),
        ("count", {"n": 3}),
        ("move", {"target": "home", "speed": 1.0}),
    ]
    assert [e.seq for e in journal.events] == list(range(1, len(journal.events) + 1))
    by = {(e.kind, e.instruction): e for e in journal.events}
    assert by[(EventKind.OPERATOR_INPUT, "1.2")].actor == "alice"
    assert by[(EventKind.CONFIRMATION, "2.1")].actor == "bob"
    assert by[(EventKind.INSTRUCTION_COMPLETED, "2.4")].actor == "bob"
    assert (
        by[(EventKind.COMMAND_SENT, "2.1")].actor == PAX
        and by[(EventKind.COMMAND_SENT, "2.1")].data.to_json()["hazardous"]
    )
    assert by[(EventKind.TELEMETRY_SEEN, "1.1")].data.to_json()["value"] == 21.5  # verify within tolerance
    assert (
        by[(EventKind.INSTRUCTION_COMPLETED, "2.6")].data.to_json()["went_to"] == "finish"
    )  # branch on a command result
    assert (
        by[(EventKind.INSTRUCTION_COMPLETED, "4.2")].data.to_json()["went_to"] == "done"
    )  # branch on a recorded input
    assert by[(EventKind.TELEMETRY_SEEN, "5.2")].data.to_json()["value"] == 21.5
    assert by[(EventKind.INSTRUCTION_COMPLETED, "5.2")].data.to_json()["went_to"] == "settle"  # branch on telemetry
    assert snap.statuses["6.1"] is InstructionStatus.COMPLETED  # a contingency step, entered by that branch
    assert by[(EventKind.CALL_ENTERED, "4.1")].data.to_json()["inputs"] == {"count": 3}
    assert by[(EventKind.COMMAND_RESULT, "4.1/1.1")].data.to_json()["values"] == {"total": 6}
    assert by[(EventKind.COMMAND_RESULT, "2.3")].data.to_json()["args"] == {
        "label": "dock_view"
    }  # a result names its request
    assert snap.statuses["3.1"] is InstructionStatus.PENDING  # the recover step was branched around
    assert snap.variables["photo"]["path"].endswith("dock_view.png")
    assert journal.events[-1].kind is EventKind.RUN_COMPLETED


def test_manual_mode_waits_for_the_operator_at_every_instruction(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.MANUAL)
    executive.start("carol")
    held(executive, Hold.MANUAL_MODE, "1.1")
    assert executive.wait_for(lambda s: s.executing or s.current != "1.1", 0.3) is None
    executive.perform("carol")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("carol", "shelf")
    held(executive, Hold.MANUAL_MODE, "1.3")
    assert gateway.sent == []
    executive.perform("carol")  # "Send"
    held(executive, Hold.MANUAL_MODE, "1.4")
    assert [c for _, c, _ in gateway.sent] == ["move"]
    executive.perform("carol")
    held(executive, Hold.CONFIRMATION, "2.1")  # a hazardous command needs confirming in manual mode too
    with pytest.raises(OperatorActionError, match="hazardous command: confirm it first"):
        executive.perform("carol")
    executive.confirm("carol")
    held(executive, Hold.MANUAL_MODE, "2.1")
    assert gateway.sent == [("lab", "move", {"target": "shelf", "speed": 0.5})]  # confirming does not send
    executive.perform("carol")
    held(executive, Hold.MANUAL_MODE, "2.2")
    sent = [e for e in journal.events if e.kind is EventKind.COMMAND_SENT]
    assert [e.actor for e in sent] == ["carol", "carol"]
    assert all(e.actor != PAX for e in journal.events if e.kind is EventKind.INSTRUCTION_STARTED)


def test_operator_switches_modes_midway(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.MANUAL)
    executive.start("dave")
    held(executive, Hold.MANUAL_MODE, "1.1")
    executive.set_mode("dave", Mode.AUTONOMOUS)
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    assert [e.actor for e in journal.events if e.kind is EventKind.INSTRUCTION_STARTED] == [PAX]
    executive.enter("dave", "dock")
    held(executive, Hold.CONFIRMATION, "2.1")
    executive.set_mode("dave", Mode.MANUAL)
    held(executive, Hold.CONFIRMATION, "2.1")
    assert [e.data.to_json()["mode"] for e in journal.events if e.kind is EventKind.MODE_CHANGED] == [
        "autonomous",
        "manual",
    ]


def test_breakpoint_holds_then_step_and_continue(bench: Bench) -> None:
    executive, gateway, journal = bench()
    executive.set_breakpoint("erin", "1.3")
    executive.start("erin")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("erin", "dock")
    held(executive, Hold.BREAKPOINT, "1.3")
    assert gateway.sent == []
    executive.step("erin")  # perform 1.3 only, then hold
    held(executive, Hold.PAUSED, "1.4")
    assert [c for _, c, _ in gateway.sent] == ["move"]
    assert next(e for e in journal.events if e.kind is EventKind.COMMAND_SENT).actor == "erin"
    executive.resume_automation("erin")
    held(executive, Hold.CONFIRMATION, "2.1")
    kinds = journal.kinds()
    order = [kinds.index(kind) for kind in (EventKind.BREAKPOINT_SET, EventKind.BREAKPOINT_HIT, EventKind.CONTINUED)]
    assert order == sorted(order)
    with pytest.raises(OperatorActionError, match="no instruction '9.9'"):
        executive.set_breakpoint("erin", "9.9")


def test_pause_holds_automation_and_stop_ends_the_run(bench: Bench) -> None:
    executive, gateway, journal = bench()
    executive.start("frank")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.pause("frank")
    executive.enter("frank", "dock")
    held(executive, Hold.PAUSED, "1.3")
    assert gateway.sent == []
    executive.stop("frank", "end of shift")
    snap = finished(executive)
    assert snap.status is RunStatus.STOPPED
    assert (
        journal.events[-1].kind is EventKind.RUN_STOPPED
        and journal.events[-1].data.to_json()["reason"] == "end of shift"
    )
    with pytest.raises(OperatorActionError, match="stopped"):
        executive.perform("frank")
    assert gateway.sent == []


def test_failed_command_holds_with_the_reason_until_retried(bench: Bench) -> None:
    executive, gateway, journal = bench()
    gateway.fail_next["move"] = "blocked by debris"
    executive.start("gina")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("gina", "dock")
    snap = held(executive, Hold.FAILURE, "1.3")
    assert "blocked by debris" in snap.reason
    assert snap.statuses["1.3"] is InstructionStatus.FAILED
    assert snap.statuses["1.4"] is InstructionStatus.PENDING  # never runs on as if it had succeeded
    failed = next(e for e in journal.events if e.kind is EventKind.INSTRUCTION_FAILED)
    assert failed.data.to_json()["next"] == "1.3"
    with pytest.raises(OperatorActionError, match="retry or skip"):
        executive.perform("gina")
    executive.retry("gina")
    held(executive, Hold.CONFIRMATION, "2.1")
    assert [c for _, c, _ in gateway.sent] == ["move", "move"]
    assert journal.kinds("1.3").count(EventKind.INSTRUCTION_COMPLETED) == 1


def test_failed_verify_branches_where_the_procedure_says(bench: Bench) -> None:
    executive, gateway, journal = bench()
    gateway.stale.add("door_open")  # the door sensor stopped reporting: a verify must not pass
    executive.start("hank")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("hank", "dock")
    held(executive, Hold.CONFIRMATION, "2.1")
    executive.confirm("hank")
    held(executive, Hold.OPERATOR_ACTION, "3.1")  # the recover step
    failed = next(e for e in journal.events if e.kind is EventKind.INSTRUCTION_FAILED)
    assert (failed.instruction, failed.data.to_json()["branch"], failed.data.to_json()["next"]) == (
        "2.2",
        "recover",
        "3.1",
    )
    assert "stale" in failed.data.to_json()["reason"]
    seen = [e for e in journal.events if e.kind is EventKind.TELEMETRY_SEEN and e.instruction == "2.2"]
    assert seen[-1].data.to_json()["stale"] is True and seen[-1].data.to_json()["ok"] is False
    assert ("lab", "capture", {"label": "dock_view"}) not in gateway.sent


def test_a_contingency_looping_back_to_itself_holds_after_three_branches_and_a_resume_keeps_the_count(
    bench: Bench, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]
) -> None:
    executive, gateway, journal = bench(name="lab_retry_loop.xml")
    gateway.failing["move"] = "blocked by debris"
    executive.start("ivy")
    snap = held(executive, Hold.FAILURE, "2.1")
    assert "already taken 3 times in this run: an operator decides" in snap.reason
    assert "blocked by debris" in snap.reason
    failed = [e for e in journal.events if e.kind is EventKind.INSTRUCTION_FAILED]
    # 1.1 into the contingency, then 2.1 back to itself three times, then the hold
    assert [(e.instruction, e.data.to_json().get("branch"), e.data.to_json()["next"]) for e in failed] == [
        ("1.1", "move_interrupted", "2.1"),
        *[("2.1", "move_interrupted", "2.1")] * 3,
        ("2.1", None, "2.1"),
    ]
    assert len(gateway.sent) == 5
    executive.stop("ivy", "runner restarted")
    executive.join(TIMEOUT)

    resumed = Executive.resume(
        check_procedure(FIXTURES / "lab_retry_loop.xml", sysreps),
        gateway,
        new_journal(journal.events),
        list(journal.events),
        "ivy",
    )
    held(resumed, Hold.FAILURE, "2.1")
    resumed.retry("ivy")  # the operator's retry fails again: it holds again, it does not loop
    snap = held(resumed, Hold.FAILURE, "2.1")
    assert "already taken 3 times" in snap.reason
    assert len(gateway.sent) == 6
    resumed.stop("teardown")


def test_skip_needs_a_reason_and_later_use_of_the_skipped_value_fails(bench: Bench) -> None:
    executive, gateway, journal = bench()
    executive.start("ivy")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    with pytest.raises(OperatorActionError, match="say why"):
        executive.skip("ivy", "  ")
    executive.skip("ivy", "target decided later")
    snap = held(executive, Hold.FAILURE, "1.3")
    assert "${target} is not bound" in snap.reason
    assert gateway.sent == []
    skipped = next(e for e in journal.events if e.kind is EventKind.INSTRUCTION_SKIPPED)
    assert (skipped.actor, skipped.data.to_json()["reason"]) == ("ivy", "target decided later")
    executive.skip("ivy", "move by hand")
    snap = held(executive, Hold.FAILURE, "1.4")  # nobody moved it: the wait for a new state fails
    assert snap.statuses["1.3"] is InstructionStatus.SKIPPED
    assert "lab.state was 'idle'" in snap.reason


def test_record_rejects_values_outside_its_constraints(bench: Bench) -> None:
    executive, gateway, journal = bench()
    executive.start("jack")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    with pytest.raises(OperatorActionError, match=r"'garage' is not one of \['dock', 'shelf'\]"):
        executive.enter("jack", "garage")
    assert executive.snapshot().current == "1.2"
    assert EventKind.OPERATOR_INPUT not in journal.kinds()
    with pytest.raises(OperatorActionError, match="is a record"):
        executive.perform("jack")


def test_listeners_see_each_event_after_it_is_journaled_and_cannot_break_the_run(bench: Bench) -> None:
    executive, gateway, journal = bench()
    seen: list[tuple[int, bool]] = []

    def observer(event: Event) -> None:
        seen.append((event.seq, event in journal.events))

    def broken(event: Event) -> None:
        raise RuntimeError("observer bug")

    executive.add_listener(broken)
    executive.add_listener(observer)
    executive.start("kim")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    assert seen and all(stored for _, stored in seen)
    assert [s for s, _ in seen] == [e.seq for e in journal.events]


def test_a_procedure_with_errors_does_not_start(sysreps: dict[str, SysRep]) -> None:
    with pytest.raises(ProcedureError, match="unknown command 'mvoe'"):
        check_procedure(FIXTURES / "broken" / "unknown_command.xml", sysreps)


def _crash_while_venting(bench: Bench) -> tuple[LabGateway, list[Event]]:
    """A run whose hazardous 2.1 (vent) was sent and has not answered: the log as a crashed runner left it."""
    first, gateway, journal = bench()
    gateway.block.add("vent")
    first.start("lena")
    held(first, Hold.OPERATOR_INPUT, "1.2")
    first.enter("lena", "dock")
    held(first, Hold.CONFIRMATION, "2.1")
    first.confirm("lena")
    # sent, no answer yet: the "crash" point (the command is recorded after the instruction starts executing)
    assert first.wait_for(
        lambda s: s.executing and s.current == "2.1" and journal.events[-1].kind is EventKind.COMMAND_SENT, TIMEOUT
    )
    journal.fail_with = RuntimeError("the runner is gone")  # it records nothing more, so it does nothing more
    return gateway, list(journal.events)


def test_resume_sends_a_command_in_flight_again_with_its_key_and_never_runs_it_twice(
    bench: Bench, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]
) -> None:
    gateway, log = _crash_while_venting(bench)
    sent = log[-1]
    assert sent.data.to_json()["key"] == "run-1/2.1/1" and sent.data.to_json()["confirmed_by"] == "lena"
    journal = new_journal(log)
    heard: list[Event] = []  # a listener given to the resume hears the re-send PAX makes at once
    resumed = Executive.resume(
        check_procedure(FIXTURES / "lab_all_kinds.xml", sysreps), gateway, journal, log, "mia", listeners=[heard.append]
    )
    try:
        # the same habitat: the re-send joins the execution still running; nobody had to decide
        assert resumed.wait_for(lambda s: s.executing and s.current == "2.1", TIMEOUT)
        gateway.release.set()
        held(resumed, Hold.OPERATOR_ACTION, "2.4")
        assert [c for _, c, _ in gateway.sent].count("vent") == 1  # executed once, whatever was re-sent
        assert gateway.resent == ["run-1/2.1/1"]
        resend = next(e for e in journal.events if e.kind is EventKind.COMMAND_SENT)
        assert (resend.actor, resend.data.to_json()["key"], resend.data.to_json()["resend"]) == (
            PAX,
            "run-1/2.1/1",
            True,
        )
        result = next(e for e in journal.events if e.kind is EventKind.COMMAND_RESULT)
        assert (result.data.to_json()["outcome"], result.data.to_json()["success"]) == ("succeeded", True)
        resumed_event = journal.events[0]
        assert resumed_event.kind is EventKind.RUN_RESUMED and resumed_event.data.to_json()["resend"] == "run-1/2.1/1"
        assert resumed_event.seq == log[-1].seq + 1
        assert heard[0].seq == resumed_event.seq and resend.seq in [e.seq for e in heard]
    finally:
        resumed.stop("teardown")


def test_resume_of_an_old_log_without_keys_holds_the_in_flight_command(
    bench: Bench, sysreps: dict[str, SysRep], tmp_path: Path, new_journal: Callable[..., RecordedJournal]
) -> None:
    gateway, log = _crash_while_venting(bench)
    unkeyed = {k: v for k, v in log[-1].data.to_json().items() if k != "key"}
    log[-1] = replace(log[-1], data=unkeyed)  # as runners wrote it before command keys
    second_gateway = LabGateway(str(tmp_path / "images"))
    second_journal = new_journal(log)
    resumed = Executive.resume(
        check_procedure(FIXTURES / "lab_all_kinds.xml", sysreps), second_gateway, second_journal, log, "mia"
    )
    try:
        snap = held(resumed, Hold.IN_FLIGHT, "2.1")
        assert "no result was recorded" in snap.reason
        assert snap.variables["target"] == "dock" and snap.variables["moved"]["arrived"] is True
        assert second_gateway.sent == []  # not resent by itself: without a key it could run twice
        with pytest.raises(OperatorActionError, match="confirm it first"):
            resumed.retry("mia")
        resumed.confirm("mia")
        resumed.retry("mia")
        held(resumed, Hold.OPERATOR_ACTION, "2.4")
        assert [c for _, c, _ in second_gateway.sent] == ["vent", "capture"]
        resend = next(e for e in second_journal.events if e.kind is EventKind.COMMAND_SENT)
        assert (resend.actor, resend.data.to_json()["key"]) == ("mia", "run-1/2.1/1")  # its first keyed attempt
    finally:
        resumed.stop("teardown")
        gateway.release.set()


def test_resume_inside_a_sub_procedure_keeps_its_inputs(
    bench: Bench, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]
) -> None:
    executive, gateway, journal = bench()
    executive.start("nina")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("nina", "dock")
    held(executive, Hold.CONFIRMATION, "2.1")
    executive.confirm("nina")
    held(executive, Hold.OPERATOR_ACTION, "2.4")
    executive.mark_done("nina")
    finished(executive)
    cut = next(
        i
        for i, e in enumerate(journal.events)
        if e.kind is EventKind.INSTRUCTION_COMPLETED and e.instruction == "4.1/1.1"
    )
    log = journal.events[: cut + 1]

    gateway2 = LabGateway()
    journal2 = new_journal(log)
    resumed = Executive.resume(
        check_procedure(FIXTURES / "lab_all_kinds.xml", sysreps), gateway2, journal2, log, "nina"
    )
    snap = finished(resumed)
    assert snap.status is RunStatus.COMPLETED
    assert [c for _, c, _ in gateway2.sent] == ["move"]  # only 5.1: nothing before the cut is repeated
    assert [e.instruction for e in journal2.events if e.kind is EventKind.INSTRUCTION_STARTED] == [
        "4.1/1.2",
        "4.2",
        "5.1",
        "5.2",
        "6.1",
    ]
    assert [e.instruction for e in journal2.events if e.kind is EventKind.INSTRUCTION_COMPLETED][:2] == [
        "4.1/1.2",
        "4.1",
    ]


def test_operator_actions_are_thread_safe_under_concurrent_users(bench: Bench) -> None:
    executive, gateway, journal = bench()
    executive.start("olga")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    outcomes: list[str] = []
    barrier = threading.Barrier(4)

    def answer(user: str) -> None:
        barrier.wait()
        try:
            executive.enter(user, "dock")
            outcomes.append("entered")
        except OperatorActionError:
            outcomes.append("refused")

    threads = [threading.Thread(target=answer, args=(f"user{i}",)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(TIMEOUT)
    assert outcomes.count("entered") == 1 and outcomes.count("refused") == 3
    assert journal.kinds().count(EventKind.OPERATOR_INPUT) == 1


def test_stop_while_watching_telemetry_halts_it_and_resume_lets_the_operator_redo_it(
    bench: Bench, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]
) -> None:
    executive, gateway, journal = bench()
    gateway.stale.add("door_open")
    executive.start("sam")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("sam", "dock")
    held(executive, Hold.CONFIRMATION, "2.1")
    executive.confirm("sam")
    assert executive.wait_for(lambda s: s.executing and s.current == "2.2", TIMEOUT)  # watching a stale door
    executive.stop("sam", "shift change")
    executive.join(TIMEOUT)
    assert EventKind.INSTRUCTION_FAILED not in journal.kinds()  # never the on-failure branch
    halted = next(e for e in journal.events if e.kind is EventKind.INSTRUCTION_HALTED)
    assert (halted.instruction, halted.actor, halted.data.to_json()["reason"], halted.data.to_json()["next"]) == (
        "2.2",
        "sam",
        "shift change",
        "2.2",
    )

    gateway.stale.clear()
    resumed = Executive.resume(
        check_procedure(FIXTURES / "lab_all_kinds.xml", sysreps),
        gateway,
        new_journal(journal.events),
        list(journal.events),
        "tess",
    )
    snap = held(resumed, Hold.HALTED, "2.2")  # the operator sees why it ended and decides
    assert snap.reason == "halted by sam: shift change (2.2 was halted before it finished)"
    resumed.retry("tess")
    held(resumed, Hold.OPERATOR_ACTION, "2.4")  # 2.2 verified again, now fresh; 2.3 captured
    resumed.stop("teardown")
