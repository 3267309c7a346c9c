"""Critical commanding in the executive: a command that needs approval is sent only once a second
operator approved it; the sender's own approval is refused, and recorded with the rule that
refused it; an approval that ran out is never sent on.

The lab bench (its ``vent`` is hazardous in its SysRep), SQLite and PostgreSQL journals in turn.
"""

from __future__ import annotations

import io
from datetime import UTC, datetime, timedelta

import pytest

from caretaker.terminal import OperatorConsole, TerminalLines, Unattended
from pride.approvals import ApprovalPolicy, CriticalLevel
from pride.events import PAX, EventKind
from pride.executive import Executive, Hold, Mode, OperatorActionError, RunStatus
from support.executive_runs import Bench, held

HAZARDOUS = ApprovalPolicy(CriticalLevel.HAZARDOUS)


class Clock:
    """The approvals' clock, moved by the test (so an expiry is tested without waiting)."""

    def __init__(self) -> None:
        self.now = datetime(2026, 11, 28, 12, 0, tzinfo=UTC)

    def __call__(self) -> datetime:
        return self.now


def test_a_hazardous_command_waits_for_a_second_operator_and_both_are_recorded(bench: Bench) -> None:
    executive, gateway, journal = bench(approvals=HAZARDOUS)
    executive.start("alice")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("alice", "dock")
    snap = held(executive, Hold.CONFIRMATION, "2.1")
    assert "needs a second operator's approval" in snap.reason and "Vent Chamber" in snap.reason
    executive.confirm("alice")  # alice sends it for approval
    snap = held(executive, Hold.APPROVAL, "2.1")
    assert snap.approval is not None and (snap.approval["sender"], snap.approval["state"]) == ("alice", "requested")
    with pytest.raises(OperatorActionError, match="a second operator must approve it, not alice"):
        executive.approve("alice")
    with pytest.raises(OperatorActionError, match="waits for a second operator's approval"):
        executive.confirm("bob")  # one request at a time
    assert [c for _, c, _ in gateway.sent] == ["move"]  # nothing sent on a request alone
    executive.approve("bob")
    held(executive, Hold.OPERATOR_ACTION, "2.4")
    assert [c for _, c, _ in gateway.sent] == ["move", "vent", "capture"]
    by = {(e.kind, e.instruction): e for e in journal.events}
    assert by[(EventKind.APPROVAL_REQUESTED, "2.1")].actor == "alice"
    # the refused self-approval is on the record, with the rule that refused it
    refused = by[(EventKind.ACTION_REFUSED, "2.1")]
    assert refused.actor == "alice" and refused.seq < by[(EventKind.APPROVAL_GIVEN, "2.1")].seq
    assert (refused.data.to_json()["action"], refused.data.to_json()["rule"]) == ("approve", "two_person")
    assert "a second operator must approve it, not alice" in refused.data.to_json()["reason"]
    assert [e.kind for e in journal.events].count(
        EventKind.ACTION_REFUSED
    ) == 1  # once (bob's confirm, refused here, is its caller's to record)
    given = by[(EventKind.APPROVAL_GIVEN, "2.1")]
    assert (
        given.actor == "bob"
        and given.data.to_json()["sender"] == "alice"
        and "Vent Chamber" in given.data.to_json()["command"]
    )
    sent = by[(EventKind.COMMAND_SENT, "2.1")]
    assert sent.actor == PAX and (sent.data.to_json()["requested_by"], sent.data.to_json()["approved_by"]) == (
        "alice",
        "bob",
    )


def _by_hand_to_the_vent(executive: Executive) -> None:
    """carol starts a manual run and performs it up to 2.1, the hazardous vent, where it holds."""
    executive.start("carol")
    executive.perform("carol")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("carol", "shelf")
    executive.perform("carol")
    held(executive, Hold.MANUAL_MODE, "1.4")
    executive.perform("carol")
    held(executive, Hold.CONFIRMATION, "2.1")


def test_in_manual_mode_send_asks_for_approval_and_the_approval_sends_it_as_the_sender(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.MANUAL, approvals=HAZARDOUS)
    _by_hand_to_the_vent(executive)
    with pytest.raises(OperatorActionError, match="send it for approval first"):
        executive.perform("carol")
    executive.confirm("carol")
    held(executive, Hold.APPROVAL, "2.1")
    executive.approve("dave")
    held(executive, Hold.MANUAL_MODE, "2.2")
    sent = [e for e in journal.events if e.kind is EventKind.COMMAND_SENT and e.instruction == "2.1"]
    assert [(e.actor, e.data.to_json()["approved_by"]) for e in sent] == [("carol", "dave")]
    assert gateway.sent[-1][1] == "vent"


def test_an_expired_approval_is_never_sent_on_and_the_command_waits_again(bench: Bench) -> None:
    clock = Clock()
    executive, gateway, journal = bench(approvals=ApprovalPolicy(CriticalLevel.HAZARDOUS, 60.0, clock))
    executive.set_breakpoint("alice", "2.1")
    executive.start("alice")
    held(executive, Hold.OPERATOR_INPUT, "1.2")
    executive.enter("alice", "dock")
    held(executive, Hold.BREAKPOINT, "2.1")
    executive.confirm("alice")
    executive.approve("bob")  # approved while automation stays at the breakpoint
    clock.now += timedelta(seconds=61)
    executive.resume_automation("alice")
    snap = held(executive, Hold.CONFIRMATION, "2.1")
    assert snap.approval == {"number": "2.1", "state": "needed", "level": "hazardous"}  # asked again, from the start
    assert [c for _, c, _ in gateway.sent] == ["move"]
    expired = [e for e in journal.events if e.kind is EventKind.APPROVAL_EXPIRED]
    assert [(e.actor, e.data.to_json()["approver"], e.data.to_json()["sender"]) for e in expired] == [
        (PAX, "bob", "alice")
    ]
    executive.confirm("alice")
    executive.approve("erin")  # a fresh approval, in time
    held(executive, Hold.OPERATOR_ACTION, "2.4")
    assert [c for _, c, _ in gateway.sent][:2] == ["move", "vent"]


def test_level_all_asks_approval_for_every_command_and_off_only_a_confirmation(bench: Bench) -> None:
    every, _, _ = bench(approvals=ApprovalPolicy(CriticalLevel.ALL), run_id="run-all")
    every.start("alice")
    held(every, Hold.OPERATOR_INPUT, "1.2")
    every.enter("alice", "dock")
    snap = held(every, Hold.CONFIRMATION, "1.3")  # move is no hazardous command, but every command needs it
    assert "needs a second operator's approval" in snap.reason

    off, _, _ = bench(approvals=ApprovalPolicy(CriticalLevel.OFF), run_id="run-off")
    off.start("alice")
    held(off, Hold.OPERATOR_INPUT, "1.2")
    off.enter("alice", "dock")
    snap = held(off, Hold.CONFIRMATION, "2.1")
    assert "is hazardous; confirm to send" in snap.reason
    off.confirm("alice")  # off: the operator's own confirmation sends it
    held(off, Hold.OPERATOR_ACTION, "2.4")


def test_at_a_terminal_a_second_operator_approves_with_their_own_password(bench: Bench) -> None:
    executive, gateway, journal = bench(approvals=HAZARDOUS)
    prompts: list[str] = []
    answers = iter(["y", "a", "bob", "a", "bob"])
    passwords = iter(["not-bobs", "bobs-password"])

    def second_operator(user: str, password: str) -> str:  # caretaker run checks the account in the database
        if (user, password) != ("bob", "bobs-password"):
            raise ValueError(f"{user}: unknown user or wrong password")
        return user

    def read(prompt: str) -> str:
        prompts.append(prompt)
        return next(answers)

    out = io.StringIO()
    console = OperatorConsole(
        executive,
        "pat",
        Unattended({"target": "dock"}, confirm_manual=True),
        interactive=True,
        out=TerminalLines(out),
        read=read,
        read_secret=lambda _prompt: next(passwords),
        second_operator=second_operator,
    )
    executive.start("pat")
    assert console.run().status is RunStatus.COMPLETED, out.getvalue()
    assert "[y] send it for a second operator's approval" in prompts[0]
    assert "[a] a second operator approves it here" in prompts[1]
    assert "not approved: bob: unknown user or wrong password" in out.getvalue()
    vent = next(e for e in journal.events if e.kind is EventKind.COMMAND_SENT and e.instruction == "2.1")
    assert (vent.data.to_json()["requested_by"], vent.data.to_json()["approved_by"]) == ("pat", "bob")
    assert [c for _, c, _ in gateway.sent].count("vent") == 1


def test_after_a_failure_an_approval_lets_the_operator_retry_and_sends_nothing_by_itself(bench: Bench) -> None:
    executive, gateway, journal = bench(Mode.MANUAL, approvals=HAZARDOUS)
    gateway.fail_next["vent"] = "chamber valve stuck"
    _by_hand_to_the_vent(executive)
    executive.confirm("carol")
    executive.approve("dave")
    snap = held(executive, Hold.FAILURE, "2.1")
    assert snap.approval == {"number": "2.1", "state": "needed", "level": "hazardous"}  # the attempt used it up
    with pytest.raises(OperatorActionError, match="send it for approval first"):
        executive.retry("carol")
    executive.confirm("carol")
    executive.approve("dave")
    held(executive, Hold.FAILURE, "2.1")  # approved, but the retry is still the operator's to ask for
    assert [c for _, c, _ in gateway.sent].count("vent") == 1
    executive.retry("carol")
    held(executive, Hold.MANUAL_MODE, "2.2")
    sent = [e for e in journal.events if e.kind is EventKind.COMMAND_SENT and e.instruction == "2.1"]
    assert [(e.data.to_json()["key"], e.data.to_json()["approved_by"]) for e in sent] == [
        ("run-1/2.1/1", "dave"),
        ("run-1/2.1/2", "dave"),
    ]
