"""The habitat's onboard runs (onboard/habitat_runs.py) on the lab bench: what a unit may start,
what the run answers by itself, operators' keyed actions, and a ground copy of the chain that
equals the habitat's hash for hash (onboard/downlink.py).

The lab bench gateway stands in for PAX's Java host here only: the IVA procedure flown onboard
across the emulated link, on the real stack, is tests/flight/test_iva_onboard.py.
"""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from pathlib import Path
from types import SimpleNamespace
from typing import Any

import pytest

from onboard.downlink import Downlink, DownlinkError, build_unit
from onboard.habitat_runs import SECURITY_LOG, HabitatRuns
from onboard.unit import OperatorAction, Unit, sign
from pride.approvals import ApprovalPolicy, CriticalLevel
from pride.events import EventKind
from pride.run_setup import load_sysreps
from pride.states import CarriedApprovalSpent, Hold, OperatorActionError, RefusalRule
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from records.audit_log import AuditLog
from support.lab_gateway import LabGateway
from support.procedures import FIXTURES, REPO

pytestmark = pytest.mark.timeout(60)

SECRET = "the link's secret"
PROCEDURE = FIXTURES / "lab_all_kinds.xml"


@pytest.fixture(scope="module")
def sysreps() -> dict[str, SysRep]:
    return load_sysreps([REPO / "sysrep", FIXTURES / "sysrep"])


@pytest.fixture
def habitat(tmp_path: Path, sysreps: dict[str, SysRep]) -> Iterator[tuple[HabitatRuns, list[LabGateway]]]:
    """The habitat's runs on the lab bench (the binding file is only named: the bench needs none)."""
    binding = tmp_path / "lab.yaml"
    binding.write_text("robot: lab\n")
    gateways: list[LabGateway] = []

    def bench(path: str, url: str | None) -> LabGateway:
        gateways.append(LabGateway())
        return gateways[-1]

    runs = HabitatRuns(
        tmp_path / "habitat", secret=SECRET, bindings={"lab.yaml": binding}, sysreps=sysreps, gateway_factory=bench
    )
    yield runs, gateways
    runs.close()


@pytest.fixture
def make_unit(sysreps: dict[str, SysRep]) -> Callable[..., Unit]:
    """A unit of ``procedure`` (default :data:`PROCEDURE`), with ``changes`` to its fields."""

    def make(procedure: Path = PROCEDURE, **changes: Any) -> Unit:
        unit = build_unit(
            check_procedure(procedure, sysreps),
            run_id=f"lab-{time.monotonic_ns()}",
            binding="lab.yaml",
            user="alice",
            mode="autonomous",
            values={"target": "dock"},
            confirm_manual=True,
            confirm_hazardous=True,
            breakpoints=(),
            lifetime_s=60,
            now=time.time(),
            policy=ApprovalPolicy(CriticalLevel.HAZARDOUS),  # the habitat's (no deployment serves lab.yaml)
            approver="bob",
        )
        return replace(unit, **changes)

    return make


def uplink(runs: HabitatRuns, unit: Unit, secret: str = SECRET) -> Any:
    text = unit.to_json()
    return runs.uplink(text, sign(text, secret))


def act(runs: HabitatRuns, action: OperatorAction) -> Any:
    text = action.to_json()
    return runs.act(text, sign(text, SECRET))


def until_ended(runs: HabitatRuns, run_id: str) -> list[dict[str, Any]]:
    """Every event of the run as it comes down, asked as the ground asks (above the last one had)."""
    events: list[dict[str, Any]] = []
    while True:
        answer = runs.events(run_id, events[-1]["seq"] if events else 0, wait_s=5)
        events += answer.events
        if answer.status != "active" and (not events or events[-1]["seq"] == answer.head_seq):
            return events


def test_a_unit_runs_onboard_answering_what_it_carries_and_the_ground_copy_is_the_habitats_chain(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit], tmp_path: Path
) -> None:
    runs, gateways = habitat
    unit = make_unit()
    answer = uplink(runs, unit)
    assert (answer.state, answer.run_id) == ("ACCEPTED", unit.run_id), answer.message
    events = until_ended(runs, unit.run_id)
    assert events[-1]["kind"] == EventKind.RUN_COMPLETED.value
    # the holds the unit answered were answered onboard, as its user
    kinds = [(e["kind"], e["actor"]) for e in events]
    assert ("operator_input", "alice") in kinds and ("approval_requested", "alice") in kinds
    assert [command for _, command, _ in gateways[0].sent].count("vent") == 1
    # the sub-procedure went up with it: its instructions ran here
    assert any(e["instruction"] and "/" in e["instruction"] for e in events)

    ground = AuditLog(f"sqlite:///{tmp_path / 'ground.sqlite'}")
    try:
        downlink = Downlink(ground, unit.run_id)
        middle = len(events) // 2
        assert len(downlink.take(events[:middle])) == middle
        assert len(downlink.take(events)) == len(events) - middle  # asked again from the start: stored once
        assert downlink.take(events) == []
        here, there = ground.stored_events(unit.run_id), runs.audit.stored_events(unit.run_id)
        assert [e.hash for e in here] == [e.hash for e in there] and ground.verify(unit.run_id).ok
    finally:
        ground.close()


def test_the_same_unit_again_is_answered_as_before_and_starts_nothing(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit]
) -> None:
    runs, gateways = habitat
    unit = make_unit()
    first, again = uplink(runs, unit), uplink(runs, unit)
    assert first.state == "ACCEPTED" and again == first
    until_ended(runs, unit.run_id)
    assert uplink(runs, unit) == first  # and after the run ended: the same answer, no second run
    assert len(gateways) == 1
    assert [e.kind for e in runs.audit.events(unit.run_id)].count(EventKind.RUN_STARTED) == 1


def test_a_refused_unit_sent_again_after_the_run_that_stopped_it_ended_stays_refused(
    habitat: tuple[HabitatRuns, list[LabGateway]],
    make_unit: Callable[..., Unit],
    tmp_path: Path,
    sysreps: dict[str, SysRep],
    caplog: pytest.LogCaptureFixture,
) -> None:
    runs, gateways = habitat
    running = make_unit()
    assert uplink(runs, running).state == "ACCEPTED"
    refused_unit = make_unit()
    with caplog.at_level(logging.WARNING, logger=SECURITY_LOG):
        refused = uplink(runs, refused_unit)
        assert refused.state == "REFUSED" and f"onboard run {running.run_id} is active" in refused.message
        until_ended(runs, running.run_id)

        # as an attacker on the link would: the same bytes, within the unit's lifetime, the robot idle
        assert uplink(runs, refused_unit) == refused
        # nor does another unit under the refused unit's run id start it
        renamed = replace(refused_unit, issued_at=refused_unit.issued_at + 1)
        other = uplink(runs, renamed)
        assert other.state == "REFUSED" and f"run {refused_unit.run_id} was answered before (REFUSED" in other.message
    assert len(gateways) == 1 and runs.audit.events(refused_unit.run_id) == []
    said = [r.getMessage() for r in caplog.records if r.name == SECURITY_LOG]
    assert len(said) == 3 and all(refused.unit_hash[:12] in line for line in said[:2]), said
    assert "sent again, refused as before" in said[1]
    status = runs.status()
    assert (status.active_run, status.units_answered, status.units_refused) == ("", 3, 3)

    # the answers outlive the executive: a restarted one answers the replay as the first did
    runs.close()
    again = HabitatRuns(
        tmp_path / "habitat",
        secret=SECRET,
        bindings={"lab.yaml": tmp_path / "lab.yaml"},
        sysreps=sysreps,
        gateway_factory=lambda path, url: pytest.fail("a replayed unit opened a gateway"),
    )
    try:
        assert uplink(again, refused_unit) == refused
        assert uplink(again, running).state == "ACCEPTED"  # accepted then, still: it starts nothing either
        assert again.status().units_refused == 1
    finally:
        again.close()


def test_refused_units_start_nothing_and_say_why(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit]
) -> None:
    runs, gateways = habitat
    forged = uplink(runs, make_unit(), secret="not the link's")
    assert forged.state == "REFUSED" and forged.message.startswith(
        "the unit's signature does not match its contents: changed on the way, or signed with another key"
    )

    late = uplink(runs, make_unit(expires_at=time.time() - 5))
    assert late.state == "EXPIRED" and "ran out" in late.message and "before it arrived; not started" in late.message

    unit = make_unit()
    broken = unit.files[unit.procedure].replace('system="lab" name="vent"', 'system="lab" name="implode"')
    unlinted = uplink(runs, replace(unit, files={**unit.files, unit.procedure: broken}))
    assert unlinted.state == "REFUSED" and "does not lint against this habitat's SysReps" in unlinted.message
    assert f"\n{unit.procedure}:19:27: unknown command 'implode' in lab" in unlinted.message  # as the ground has it

    elsewhere = uplink(runs, make_unit(binding="eva.yaml"))
    assert (
        elsewhere.state == "REFUSED" and "no binding 'eva.yaml' on this habitat (it has: lab.yaml)" in elsewhere.message
    )

    assert gateways == [] and runs.audit.runs() == []  # none of them started a run or left a record


def test_a_second_unit_is_refused_while_one_runs_and_the_ground_answers_a_hold_once_per_key(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit]
) -> None:
    runs, _ = habitat
    unit = make_unit(values={})  # the record is not answered at uplink: the run holds for the ground
    assert uplink(runs, unit).state == "ACCEPTED"
    held = runs.events(unit.run_id, 0)
    while not any(e["kind"] == "awaiting_operator" for e in held.events):
        held = runs.events(unit.run_id, 0, wait_s=5)
    second = uplink(runs, make_unit())
    assert second.state == "REFUSED" and f"onboard run {unit.run_id} is active" in second.message
    waiting = ""
    while not waiting:  # once the run's answerer has left the hold to the ground, the ground hears so
        waiting = runs.events(unit.run_id, held.head_seq, wait_s=0.5).waiting
    assert waiting.startswith("1.2: "), waiting
    state = runs.events(unit.run_id, held.head_seq).snapshot  # the executive's own state, as of an event sent
    assert state is not None and state["current"] == "1.2" and state["hold"] is not None
    assert state["last_seq"] <= runs.events(unit.run_id, 0).head_seq

    # clicked on an instruction the run has left (the ground saw it a light time ago): refused
    late = OperatorAction("key-0", unit.run_id, "enter", "bob", time.time() + 60, {"value": "x", "instruction": "1.1"})
    refused = act(runs, late)
    assert refused.state == "REFUSED" and refused.message == "enter was for 1.1, the run is at 1.2: not acted on"
    entered = OperatorAction(
        "key-1", unit.run_id, "enter", "bob", time.time() + 60, {"value": "dock", "instruction": "1.2"}
    )
    assert act(runs, entered).state == "DONE"
    assert act(runs, entered).state == "DONE"  # a resend: answered from the record, not entered again
    until_ended(runs, unit.run_id)
    inputs = [e for e in runs.audit.events(unit.run_id) if e.kind is EventKind.OPERATOR_INPUT]
    assert [(e.actor, e.data.to_json()["value"]) for e in inputs] == [("bob", "dock")]

    stale = OperatorAction("key-2", unit.run_id, "halt", "bob", time.time() - 1, {"reason": "late"})
    assert act(runs, stale).state == "EXPIRED"
    over = OperatorAction("key-3", unit.run_id, "halt", "bob", time.time() + 60, {"reason": "done already"})
    assert act(runs, over).state == "REFUSED"  # the run ended: nothing to halt
    forged = OperatorAction("key-4", unit.run_id, "halt", "eve", time.time() + 60, {"reason": "x"}).to_json()
    assert runs.act(forged, sign(forged, "guess")).state == "REFUSED"


def test_the_ground_refuses_a_copy_that_is_not_the_habitats_chain(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit], tmp_path: Path
) -> None:
    runs, _ = habitat
    unit = make_unit()
    uplink(runs, unit)
    events = until_ended(runs, unit.run_id)
    ground = AuditLog(f"sqlite:///{tmp_path / 'ground.sqlite'}")
    try:
        downlink = Downlink(ground, unit.run_id)
        assert downlink.take([events[0], events[2]]) != [] and downlink.head_seq == 1  # a gap ends the batch
        changed = dict(events[1], data=json.dumps({**json.loads(events[1]["data"]), "forged": True}, sort_keys=True))
        with pytest.raises(DownlinkError, match="event 2's contents do not match its hash: not stored"):
            downlink.take([changed])
        with pytest.raises(DownlinkError, match="event field seq must be int"):
            downlink.take([dict(events[1], seq="2")])
        assert downlink.head_seq == 1 and len(ground.events(unit.run_id)) == 1
    finally:
        ground.close()


def test_a_restarted_onboard_executive_resumes_its_run_from_the_chain(
    habitat: tuple[HabitatRuns, list[LabGateway]],
    make_unit: Callable[..., Unit],
    sysreps: dict[str, SysRep],
    tmp_path: Path,
) -> None:
    runs, gateways = habitat
    unit = make_unit(values={})  # it holds at the record until the ground answers
    assert uplink(runs, unit).state == "ACCEPTED"
    while not any(e["kind"] == "awaiting_operator" for e in runs.events(unit.run_id, 0, wait_s=5).events):
        pass
    runs.close()  # the executive goes away mid-run (caretaker up restarts it)

    again = HabitatRuns(
        tmp_path / "habitat",
        secret=SECRET,
        bindings={"lab.yaml": tmp_path / "lab.yaml"},
        sysreps=sysreps,
        gateway_factory=lambda path, url: gateways[0],
    )
    try:
        assert again.resume_interrupted() == [unit.run_id]
        assert uplink(again, unit).message == f"started {unit.procedure}"  # it knows the unit: the first answer
        entered = OperatorAction("key-r", unit.run_id, "enter", "bob", time.time() + 60, {"value": "dock"})
        assert act(again, entered).state == "DONE"
        events = until_ended(again, unit.run_id)
        assert events[-1]["kind"] == EventKind.RUN_COMPLETED.value
        resumed = [e for e in events if e["kind"] == EventKind.RUN_RESUMED.value]
        assert [e["actor"] for e in resumed] == ["onboard"]
        assert again.audit.verify(unit.run_id).ok
        assert again.resume_interrupted() == []  # nothing left to resume
    finally:
        again.close()


def test_the_approvals_given_on_the_ground_go_up_signed_and_the_habitat_sends_on_them(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit]
) -> None:
    runs, gateways = habitat
    unit = make_unit()
    assert [(a.instruction, a.command, a.sender, a.approver) for a in unit.approvals] == [
        ("2.1", "lab.vent", "alice", "bob")
    ]
    assert uplink(runs, unit).state == "ACCEPTED"
    events = until_ended(runs, unit.run_id)
    assert events[-1]["kind"] == EventKind.RUN_COMPLETED.value
    at_vent = [(e["kind"], e["actor"], json.loads(e["data"])) for e in events if e["instruction"] == "2.1"]
    asked = next(data for kind, actor, data in at_vent if kind == "approval_requested" and actor == "alice")
    given = next(data for kind, actor, data in at_vent if kind == "approval_given" and actor == "bob")
    assert given["carried"] is True and given["sender"] == "alice" and given["command"] == asked["command"]
    assert given["given"].startswith(time.strftime("%Y-%m-%dT", time.gmtime(unit.approvals[0].approved_at)))
    sent = next(data for kind, _, data in at_vent if kind == "command_sent")
    assert sent["approved_by"] == "bob"
    assert [command for _, command, _ in gateways[0].sent].count("vent") == 1

    # the signature covers the approvals: one added on the way is not the link's unit
    forged = replace(unit, run_id=f"{unit.run_id}-x", approvals=(replace(unit.approvals[0], approver="eve"),))
    text = forged.to_json()
    assert runs.uplink(text, sign(unit.to_json(), SECRET)).state == "REFUSED"


def test_an_approval_that_ran_out_on_the_way_is_recorded_and_a_second_operator_approves_from_the_ground(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit]
) -> None:
    runs, gateways = habitat
    unit = make_unit()
    now = time.time()
    ran_out = replace(unit.approvals[0], approved_at=now - 400, expires_at=now - 100)
    unit = replace(unit, approvals=(ran_out,))
    assert uplink(runs, unit).state == "ACCEPTED"
    head = 0
    while not any(e["kind"] == "approval_expired" for e in runs.events(unit.run_id, 0).events):
        head = runs.events(unit.run_id, head, wait_s=1).head_seq
    expired = next(e for e in runs.events(unit.run_id, 0).events if e["kind"] == "approval_expired")
    assert (expired["actor"], expired["instruction"]) == ("bob", "2.1")
    assert "vent" not in [command for _, command, _ in gateways[0].sent]  # nothing sent on a stale approval

    own = OperatorAction("key-own", unit.run_id, "approve", "alice", time.time() + 60, {"instruction": "2.1"})
    refused = act(runs, own)
    assert refused.state == "REFUSED" and "a second operator must approve it, not alice" in refused.message
    live = OperatorAction("key-carol", unit.run_id, "approve", "carol", time.time() + 60, {"instruction": "2.1"})
    assert act(runs, live).state == "DONE"
    events = until_ended(runs, unit.run_id)
    assert events[-1]["kind"] == EventKind.RUN_COMPLETED.value
    given = [(e["actor"], json.loads(e["data"]).get("carried")) for e in events if e["kind"] == "approval_given"]
    assert given == [("carol", None)]
    assert [command for _, command, _ in gateways[0].sent].count("vent") == 1


class _RefusingExecutive:
    """An executive held at PROCEDURE's 2.1 for approval whose ``approve`` refuses with ``refusal``."""

    def __init__(self, path: Path, instruction: Any, refusal: OperatorActionError) -> None:
        self.place, self.refusal, self.approvers = (path, instruction), refusal, []

    def current_place(self) -> tuple[Path, Any]:
        return self.place

    def approve(self, user: str, *, carried: Any) -> None:
        self.approvers.append(user)
        raise self.refusal


@pytest.mark.parametrize(
    ("refusal", "spent"),
    [
        (OperatorActionError("2.1 waits for no approval"), False),
        (OperatorActionError("2.1 is being performed; wait for it to finish"), False),
        (CarriedApprovalSpent("bob's approval of 2.1, carried with the unit, ran out"), True),
        (OperatorActionError("a second operator must approve it", rule=RefusalRule.TWO_PERSON, recorded=True), True),
    ],
)
def test_a_carried_approval_is_given_up_only_for_a_refusal_that_cannot_change(
    make_unit: Callable[..., Unit],
    sysreps: dict[str, SysRep],
    tmp_path: Path,
    refusal: OperatorActionError,
    spent: bool,
) -> None:
    """A refusal of the run's state of the moment (a snapshot already out of date) leaves the
    approval to be tried at the run's next event; only one that stays true hands it to the ground."""
    unit = make_unit()
    instruction = check_procedure(PROCEDURE, sysreps).procedure.instruction("2.1")
    executive = _RefusingExecutive(tmp_path / unit.procedure, instruction, refusal)
    stale: set[Any] = set()
    with pytest.raises(OperatorActionError):
        HabitatRuns._answer_hold(executive, unit, SimpleNamespace(hold=Hold.APPROVAL), tmp_path, stale)
    assert executive.approvers == ["bob"]
    assert stale == ({unit.approvals[0]} if spent else set())


def test_the_unit_a_run_started_from_is_given_to_a_ground_that_attaches(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit]
) -> None:
    runs, _ = habitat
    unit = make_unit()
    accepted = uplink(runs, unit)
    answer = runs.unit_of(unit.run_id)
    assert (answer.unit_json, answer.unit_hash) == (unit.to_json(), accepted.unit_hash)
    assert Unit.from_json(answer.unit_json) == unit
    refused = make_unit()
    assert uplink(runs, refused).state == "REFUSED"  # the robot is busy: no run of it, so no unit to attach to
    missing = runs.unit_of(refused.run_id)
    assert missing.unit_json == "" and f"no onboard run {refused.run_id}" in missing.message
    until_ended(runs, unit.run_id)


def test_a_unit_of_part_of_a_procedure_runs_that_part_and_one_missing_what_it_skips_is_refused(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit]
) -> None:
    runs, gateways = habitat
    missing = make_unit(section={"from": "finish", "to": "finish"}, values={})
    refused = uplink(runs, missing)
    assert refused.state == "REFUSED", refused
    assert "the unit's section cannot start: --from finish: the steps it skips would have bound target" in (
        refused.message
    )
    unit = make_unit(section={"from": "finish", "to": "finish"})
    assert uplink(runs, unit).state == "ACCEPTED"
    events = until_ended(runs, unit.run_id)
    assert json.loads(events[0]["data"])["section"] == {"from": "finish", "to": "finish", "given": {"target": "dock"}}
    started = [e["instruction"] for e in events if e["kind"] == "instruction_started"]
    assert started[0] == "4.1" and not [n for n in started if n.startswith(("1.", "2.", "5."))]
    assert events[-1]["kind"] == "run_completed"


def test_an_onboard_run_watches_its_monitors_a_red_limit_mid_motion_halts_it_and_goes_to_the_contingency(
    habitat: tuple[HabitatRuns, list[LabGateway]], make_unit: Callable[..., Unit], tmp_path: Path
) -> None:
    """The habitat's executive watches a unit's monitors itself: no ground is in the loop of a
    violation, which must halt the motion within the habitat's own reaction time, not a round trip.
    The robot answers the halt after the motion ended, and the unit answers nothing in the
    contingency that would hold the run there: the halt must still be on the record, before the go-to."""
    runs, gateways = habitat
    unit = make_unit(FIXTURES / "lab_monitors.xml", values={}, breakpoints=("1.1",))
    assert uplink(runs, unit).state == "ACCEPTED"
    while not any(e["kind"] == "breakpoint_hit" for e in runs.events(unit.run_id, 0, wait_s=5).events):
        pass  # at the breakpoint before the motion: the bench's motion is made to last until halted
    gateway = gateways[0]
    gateway.block.add("move")
    stop = gateway.cancel

    def answered_once_the_run_saw_the_motion_end(key: str) -> Any:
        answer = stop(key)  # the motion stops now; the answer comes once the run recorded its end
        seq = 0
        while not _recorded(runs, unit, "command_result"):
            seq = runs.events(unit.run_id, seq, wait_s=1.0).head_seq  # until a newer event is stored
        return answer

    gateway.cancel = answered_once_the_run_saw_the_motion_end
    assert act(runs, OperatorAction("key-m", unit.run_id, "continue", "bob", time.time() + 60, {})).state == "DONE"
    assert gateway.blocking.wait(10)  # the arm moves
    gateway.set("temperature", 46.0)
    gateway.set("temperature", 47.0)  # two samples above the red limit: the item's persistence
    assert gateway.cancel_seen.wait(10), "the motion was never halted"
    events = until_ended(runs, unit.run_id)
    kinds = [e["kind"] for e in events]
    violated = events[kinds.index("monitor_violated")]
    assert violated["instruction"] == "1.1" and violated["actor"] == "PAX"
    assert json.loads(violated["data"])["value"] == 47.0
    assert json.loads(violated["data"])["action"] == "goto:cool"
    assert gateway.cancels == [f"{unit.run_id}/1.1/1"]  # the motion in flight was cancelled, here
    halt = events[kinds.index("halt")]
    assert halt["actor"] == "PAX" and kinds.index("halt") < kinds.index("went_to"), kinds
    went = json.loads(events[kinds.index("went_to")]["data"])
    assert (went["from"], went["next"]) == ("1.1", "2.1")
    assert kinds[-1] == "run_completed" and [c for _, c, _ in gateway.sent] == ["move"]  # never the capture
    ground = AuditLog(f"sqlite:///{tmp_path / 'ground.sqlite'}")
    try:
        Downlink(ground, unit.run_id).take(events)
        here, there = ground.stored_events(unit.run_id), runs.audit.stored_events(unit.run_id)
        assert [(e.kind, e.hash) for e in here] == [(e.kind, e.hash) for e in there]
    finally:
        ground.close()


def _recorded(runs: HabitatRuns, unit: Unit, kind: str) -> bool:
    """Whether the run's stored events hold one of ``kind``."""
    return any(e["kind"] == kind for e in runs.events(unit.run_id, 0).events)
