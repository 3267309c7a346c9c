"""PAX: the executive that runs one procedure with an operator, in manual or autonomous mode.

One :class:`Executive` per run. It owns the run's state; everything else either *acts* on it
through the operator methods below (each takes the acting user's id and is recorded under that
id) or *observes* it (listeners, snapshots) without changing it. All methods are thread-safe:
a terminal, a web view serving several users, and tests may call them from any thread.

Modes (:class:`Mode`)
    MANUAL: nothing happens until an operator acts: :meth:`perform` sends the current command
    ("Send"), checks a verify, starts a wait, evaluates a branch; :meth:`enter` answers a record;
    :meth:`mark_done` completes a manual instruction.
    AUTONOMOUS: PAX (actor ``"PAX"``) performs every automatable instruction in turn and monitors
    its completion. It holds (:class:`Hold`) at records, manual and non-automatable instructions,
    unconfirmed hazardous commands, breakpoints, failures, halts, unknown outcomes, lost control
    and operator pauses, and carries on by itself once an operator has acted.

Operator actions (raise :class:`OperatorActionError` saying why when not applicable now)
    start, set_mode, pause, resume_automation ("continue"), halt, stop, set_breakpoint,
    clear_breakpoint, perform, step, confirm, approve, enter, correct_record, mark_done, retry,
    ask_again, resolve, skip, go_back, replan, take_control.

Critical commanding (:mod:`pride.approvals`)
    A command that needs approval holds until its sender sends it for approval (:meth:`confirm`)
    and another operator approves it (:meth:`approve`); then it is sent, ``command_sent`` naming
    both. An approval that runs out first is recorded (APPROVAL_EXPIRED); a new one is needed.

Commands and their outcomes
    Every command carries a key ``run/instruction/attempt`` (:func:`pride.automation.command_key`);
    the habitat executes a key at most once. A retry after a failure or a halt is a new attempt.
    An UNKNOWN outcome holds the run (Hold.OUTCOME_UNKNOWN) and is never shown as success or
    failure: :meth:`ask_again` re-sends the same key (the habitat answers or joins it),
    :meth:`resolve` records what the operator found on the robot, :meth:`skip` passes over it.

Halt and stop
    :meth:`halt` cancels the command in flight through the gateway *before* it takes the lock
    (so it works while the lock is held by an append waiting out a database outage), then holds
    the run (Hold.HALTED); the instruction is recorded as halted by that user, never completed.
    :meth:`stop` halts the same way, takes back what the run added to its systems (its AT
    instances, :mod:`pride.leftovers`), then ends the run. A run that took nothing back can be
    resumed; one that did cannot (what it worked on is gone). What a run leaves behind, stopped
    or completed, is listed in its end event (``left_behind``), never passed over.

After a halted motion
    Its plan ended with the halt (:mod:`pride.replanning`): retry and continue are refused, saying
    why. :meth:`replan` steps back to the instruction that planned it, so the run plans again from
    where the arm is (the snapshot's ``replan_from``, and ``no_retry`` saying why).

Monitors
    A step's ``<monitor>`` is watched on every telemetry update while active (:mod:`pride.monitoring`):
    violated, the run holds, halts, or halts and goes to a contingency step (:meth:`divert`).

Control of the robot
    With a :class:`pride.run_control.ControlStore`, a run takes control of its robot when it starts
    or resumes (refused, :class:`RobotControlled`, while another run holds it, unless it takes over
    with a reason), checks it before every command, holds (Hold.CONTROL_LOST) when another run took
    over, and releases it when it completes or stops.

Links
    A lost link is recorded (LINK_LOST, LINK_RESTORED) and shown in the snapshot. Commands in flight
    wait for it within the binding's outage budget (their keys sent again), past it they come back
    UNKNOWN. Verifies and waits count the link's one-way delay into their timeout.

Failure
    A failed command, verify or wait (or an unbound variable) never counts as done: the run goes
    to the instruction's ``on-failure`` step if it has one, else holds with Hold.FAILURE and the
    reason until an operator retries or skips it.

Observation
    :meth:`add_listener` registers ``callback(event)`` for every :class:`~pride.events.Event`,
    called after the event is durably in the journal, on the thread that caused it, while the
    executive's lock is held: listeners must be quick, must not block, and must not call operator
    actions (hand events to a queue instead). :meth:`snapshot` returns an immutable
    :class:`Snapshot`, at once even while an append waits for the database (then the state from
    before that append, with the journal's and the links' state now); :meth:`wait_for` blocks
    until a snapshot meets a predicate.

Durability
    Every event goes to the journal (the audit log) before the run proceeds; if the journal fails,
    the run stops at once with its reason (:class:`JournalFailure`) and nothing more happens.
    :meth:`resume` rebuilds a run from its events (:mod:`pride.replay`): it continues after the
    last completed instruction, and a command whose outcome was not known (in flight at the
    crash, or UNKNOWN) is sent again with its same key by itself; only if that answer is UNKNOWN
    does the run hold.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path
from typing import Any

from pride.accepted_proposal import AcceptedProposal
from pride.ad_hoc_commands import record_sent, send_recorded
from pride.ad_hoc_commands import take_back as take_back_holdings
from pride.approvals import ApprovalPolicy, CarriedApproval
from pride.automation import ControlLost, Halt
from pride.event_payloads import (
    ActionRefused,
    BreakpointCleared,
    BreakpointSet,
    Continued,
    ModeChanged,
    OperatorInput,
    Paused,
    RecordCorrected,
    Retry,
    RunStarted,
    RunStopped,
)
from pride.event_payloads import Halt as HaltRecord
from pride.events import Event, Journal
from pride.monitoring import respond
from pride.phrasing import filled_sentence
from pride.replay import resumable_start
from pride.run_control import ControlStore, RobotControlled
from pride.run_engine import RunEngine
from pride.run_section import RunSection
from pride.run_state import Request
from pride.run_version import RunVersion
from pride.states import Hold, InstructionStatus, JournalFailure, Mode, OperatorActionError, RunStatus, Snapshot
from pride.systems import CancelResult, CommandResult, Outcome, SystemGateway
from procedure_language.lint import CheckedProcedure
from procedure_language.model import Instruction, ManualInstruction, RecordInstruction

__all__ = [
    "Executive",
    "Hold",
    "InstructionStatus",
    "JournalFailure",
    "Mode",
    "OperatorActionError",
    "RobotControlled",
    "RunStatus",
    "Snapshot",
]

log = logging.getLogger(__name__)


class Executive:
    """Runs one procedure; see the module docstring for the API contract."""

    def __init__(
        self,
        checked: CheckedProcedure,
        gateway: SystemGateway,
        journal: Journal,
        *,
        run_id: str,
        mode: Mode = Mode.MANUAL,
        control: ControlStore | None = None,
        approvals: ApprovalPolicy | None = None,
        version: RunVersion | None = None,
    ) -> None:
        """Prepare a run (nothing happens until :meth:`start`); the arguments are those of the engine that runs it."""
        self._engine = RunEngine(
            checked, gateway, journal, run_id=run_id, mode=mode, control=control, approvals=approvals, version=version
        )
        # the engine's state and the lock and condition that guard it, which every action takes
        self._state, self._lock, self._changed = self._engine.state, self._engine.lock, self._engine.changed
        self._engine.on_monitor = partial(respond, self)
        self.procedure, self.run_id, self.robot, self.version = checked.procedure, run_id, self._engine.robot, version

    # ---- observation (the engine's) ---------------------------------------------------------
    def add_listener(self, callback: Callable[[Event], None]) -> None:
        """Call ``callback(event)`` for every event from now on (see Observation above)."""
        self._engine.add_listener(callback)

    def remove_listener(self, callback: Callable[[Event], None]) -> None:
        self._engine.remove_listener(callback)

    def snapshot(self) -> Snapshot:
        """The run's state now (never waits for the database)."""
        return self._engine.snapshot()

    def wait_for(self, predicate: Callable[[Snapshot], bool], timeout: float | None = None) -> Snapshot | None:
        """Block until ``predicate(snapshot)`` holds; return that snapshot, or None on timeout."""
        return self._engine.wait_for(predicate, timeout)

    def wait_for_report(self, system: str, item: str, timeout: float) -> bool:
        """Block until ``system`` reports ``item`` afresh (:meth:`pride.run_engine.RunEngine.wait_for_report`)."""
        return self._engine.wait_for_report(system, item, timeout)

    def current_instruction(self) -> Instruction | None:
        """The instruction the run is at (in the innermost sub-procedure), or None when finished."""
        return self._engine.current_instruction()

    def current_place(self) -> tuple[Path, Instruction] | None:
        """The file of the (sub-)procedure the run is in and its instruction there, or None when finished."""
        return self._engine.current_place()

    def join(self, timeout: float | None = None) -> None:
        """Wait for PAX's thread to end (after the run completed or stopped)."""
        self._engine.join(timeout)

    # ---- lifecycle --------------------------------------------------------------------------
    def start(
        self,
        user: str,
        *,
        take_over: str | None = None,
        section: RunSection | None = None,
        proposal: AcceptedProposal | None = None,
    ) -> None:
        """Begin the run (called once, by whoever launches it); take control of the robot first.
        ``section``: run part of the procedure (:mod:`pride.run_section`); ``proposal``: the
        agent's proposal an operator accepted to start it, recorded with the start.

        Raises:
            RobotControlled: another run controls the robot (and ``take_over`` gives no reason to
                take it from that run); nothing is recorded then.
            SectionError: the section cannot start (what to fix); nothing is recorded then.
        """
        with self._changed:
            state = self._state
            if state.status is not RunStatus.READY:
                raise OperatorActionError(f"run {self.run_id} was already started")
            if section is not None:
                variables = section.check(self._engine.checked)
                state.enter_section(section.start, variables, section.stops_after(self.procedure))
            previous = self._engine.control.take(user, take_over)
            state.status = RunStatus.ACTIVE
            procedure, version = self.procedure, self.version
            started = RunStarted(
                procedure=procedure.id,
                title=procedure.title,
                version=procedure.version,
                path=str(Path(procedure.path).resolve()),
                mode=state.mode.value,
                robot=self.robot,
                steps=tuple({"number": s.number, "id": s.id, "title": s.title} for s in procedure.steps),
                sha256=version.sha256 if version else None,
                release=version.release if version else None,
                rehearsal=version.rehearsal if version else None,
                section=section.to_json() if section else None,
                proposal=proposal.to_json() if proposal else None,
            )
            self._engine.emit(user, None, started)
            self._engine.record_takeover(user, previous, take_over)
            state.arrive()
            self._engine.launch()

    @classmethod
    def resume(
        cls,
        checked: CheckedProcedure,
        gateway: SystemGateway,
        journal: Journal,
        events: list[Event],
        user: str,
        *,
        mode: Mode | None = None,
        control: ControlStore | None = None,
        take_over: str | None = None,
        approvals: ApprovalPolicy | None = None,
        listeners: Sequence[Callable[[Event], None]] = (),
    ) -> Executive:
        """Continue an interrupted run from its recorded events (see Durability above); an
        approval given before the interruption is not carried over (it is asked again).

        ``listeners`` get every event of the resumed run, from its ``run_resumed`` on: they are
        attached before PAX's thread starts, which may at once send again a command in flight.
        """
        started = resumable_start(checked.procedure.id, events)  # OperatorActionError: why it cannot go on
        run_id = events[0].run_id
        mode_was = Mode(started.mode or "manual")
        executive = cls(checked, gateway, journal, run_id=run_id, mode=mode_was, control=control, approvals=approvals)
        executive._engine.resume_from(events, user, mode=mode, take_over=take_over, listeners=listeners)
        return executive

    # ---- control of the robot -----------------------------------------------------------------
    def take_control(self, user: str, reason: str) -> None:
        """Take control of the robot back from the run that took it over (``reason`` required)."""
        with self._changed:
            self._engine.require_active()
            if self._engine.control.control is None:
                raise OperatorActionError("this run is not under robot control")
            if self._state.control_lost is None:
                raise OperatorActionError(f"run {self.run_id} already controls robot {self.robot}")
            _require_reason(reason, "you take control of the robot")
            self._engine.record_takeover(user, self._engine.control.take(user, reason), reason)
            self._state.control_lost = None
            self._state.announce()

    # ---- operator actions -------------------------------------------------------------------
    def set_mode(self, user: str, mode: Mode) -> None:
        """Switch between manual and autonomous execution."""
        with self._changed:
            self._engine.require_active()
            if mode is self._state.mode:
                return
            self._state.mode = mode
            self._engine.emit(user, self._state.current_number(), ModeChanged(mode=mode.value))
            self._state.announce()

    def pause(self, user: str) -> None:
        """Stop automation after the instruction in progress (autonomous mode stays selected)."""
        with self._changed:
            self._engine.require_active()
            if self._state.paused:
                return
            self._state.paused = True
            self._engine.emit(user, self._state.current_number(), Paused())

    def resume_automation(self, user: str) -> None:
        """Carry on after a pause, a breakpoint or a halt ("continue")."""
        with self._changed:
            self._engine.require_active()
            state = self._state
            if not (state.paused or state.at_breakpoint or state.halt):
                raise OperatorActionError("automation is neither paused, halted nor at a breakpoint")
            if state.halt and state.executing:
                raise OperatorActionError(f"{state.current_number()} is still ending after the halt; wait for it")
            replan = self._engine.halted_motion() if state.halt else None
            if replan is not None:  # automation would send the halted motion again: it cannot work
                raise OperatorActionError(replan.why_not_again())
            state.paused = state.at_breakpoint = False
            self._engine.clear_halt()
            self._engine.emit(user, state.current_number(), Continued())
            state.announce()

    def halt(self, user: str, reason: str = "") -> None:
        """Stop the robot now: cancel the command in flight, then hold (never refused while the run is live).

        The cancel goes to the gateway before the executive's lock is taken, so it reaches the
        robot even while the lock is held by an append that waits for the database.
        """
        carried_on = self._state.carried_on
        key = self._engine.automation.request_halt(Halt(user, reason)) or self._engine.pending_key()
        answer = self._engine.cancel(key)
        with self._changed:
            state = self._state
            if state.status is not RunStatus.ACTIVE:
                return
            if state.halt is None and state.carried_on == carried_on:  # not after an operator carried on
                state.halt = Halt(user, reason)
            halted = HaltRecord(reason=reason, key=key, cancel=_cancel_data(answer), executing=state.executing)
            self._engine.record_halt(user, halted)
            state.announce()

    def stop(self, user: str, reason: str = "", *, take_back: bool = True) -> None:
        """Halt as :meth:`halt` does, take back what the run added to its systems, then end the run.

        Taking back waits for the command in flight to end (the halt cancelled it; its answer may
        add an instance), then removes each instance the run added and still holds, as ``user``,
        through the gateway and the journal like any command (:meth:`_take_back`). RUN_STOPPED
        lists what was taken back and what is left behind, and why. ``take_back=False`` leaves
        everything for a resume elsewhere (a console shutting down, or one that lost the run to
        another host), listed all the same; such a run can be resumed, one that took back cannot.
        """
        key = self._engine.automation.request_halt(Halt(user, reason)) or self._engine.pending_key()
        answer = self._engine.cancel(key)
        with self._changed:
            self._engine.require_active()
            state = self._state
            if take_back:
                state.stopping = True  # the run moves on no more, and nobody else acts on it
                self._changed.wait_for(lambda: not state.executing or state.status is not RunStatus.ACTIVE)
                if state.status is not RunStatus.ACTIVE:  # its journal failed meanwhile: nothing more unrecorded
                    raise JournalFailure(f"run {self.run_id} stopped: {state.error}")
                ended = take_back_holdings(self._engine, user)
            else:
                ended = self._engine.holdings.left("kept for a resume of the run")
            state.status = RunStatus.STOPPED
            stopped = RunStopped(
                reason=reason,
                key=key,
                cancel=_cancel_data(answer),
                taken_back=ended.removed,
                left_behind=ended.left_json(),
            )
            self._engine.emit(user, state.current_number(), stopped)

    def divert(self, step: str, reason: str) -> bool:
        """A monitor's go-to: to ``step`` once what runs ends (True: halt it), at once if nothing runs."""
        return self._engine.divert(step, reason)

    def set_breakpoint(self, user: str, number: str) -> None:
        """Make automation hold when it reaches instruction ``number``."""
        with self._changed:
            self._check_number(number)
            if number not in self._state.breakpoints:
                self._state.breakpoints.add(number)
                self._engine.emit(user, number, BreakpointSet())

    def clear_breakpoint(self, user: str, number: str) -> None:
        with self._changed:
            if number in self._state.breakpoints:
                self._state.breakpoints.discard(number)
                self._engine.emit(user, number, BreakpointCleared())

    def perform(self, user: str) -> None:
        """Perform the current instruction as ``user`` ("Send", "Check", "Start"); PAX carries it out."""
        self._request_perform(user, then_pause=False)

    def step(self, user: str) -> None:
        """Perform the current instruction, then hold automation at the next one."""
        self._request_perform(user, then_pause=self._state.mode is Mode.AUTONOMOUS)

    def _request_perform(self, user: str, *, then_pause: bool) -> None:
        with self._changed:
            instruction = self._engine.require_idle()
            state = self._state
            number = state.current_number()
            if isinstance(instruction, (RecordInstruction, ManualInstruction)):
                todo = "enter a value" if isinstance(instruction, RecordInstruction) else "mark it done"
                raise OperatorActionError(f"{number} is a {instruction.kind.value}: {todo}")
            if state.unknown or state.resend:
                raise OperatorActionError(self._engine.unknown_text())
            if state.failure or state.in_flight:
                raise OperatorActionError(f"{number} failed or was interrupted: retry or skip it")
            if state.halt:
                replan = self._engine.halted_motion()
                way = replan.why_not_again() if replan else "continue, retry or skip first"
                raise OperatorActionError(f"the run is {state.halt_text()}: {way}")
            if state.control_lost:
                raise OperatorActionError(f"{state.control_lost}: take control first")
            if state.unconfirmed(instruction):
                raise OperatorActionError(state.unconfirmed_text(number, instruction))
            state.request = Request(user, then_pause)
            state.at_breakpoint = False
            self._changed.notify_all()

    def confirm(self, user: str) -> None:
        """Confirm the current hazardous command (needed before it is sent, in either mode); under
        critical commanding, send it for a second operator's approval, ``user`` its sender."""
        with self._changed:
            instruction = self._engine.require_idle()
            frame = self._state.frame
            said = filled_sentence(instruction, self._engine.checked.sysreps, frame.procedure, frame.env)
            self._state.confirm(user, instruction, said)

    def approve(self, user: str, *, carried: CarriedApproval | None = None) -> None:
        """Approve the command sent for approval, as the second operator: it is sent at once (by
        PAX, or in manual mode as its sender). The sender's own approval is refused, and recorded.

        ``carried``: ``user``'s approval given on the ground before an onboard unit went up; it
        keeps the time it was given and its expiry, and a stale one is refused."""
        with self._changed:
            self._engine.require_idle()
            self._state.approve(user, carried)

    def enter(self, user: str, value: Any) -> Any:
        """Answer the current record; returns the value as recorded (converted to its type)."""
        with self._changed:
            instruction = self._engine.require_idle()
            if not isinstance(instruction, RecordInstruction):
                raise OperatorActionError(f"{self._state.current_number()} is a {instruction.kind.value}, not a record")
            converted, against, allowed = self._engine.automation.check_record(instruction, value)
            frame = self._state.frame
            frame.env[instruction.name] = converted
            entered = OperatorInput(name=instruction.name, value=converted, checked_against=against, allowed=allowed)
            self._engine.emit(user, frame.number(), entered)
            self._state.complete(user, frame.procedure.following(frame.position))
            return converted

    def correct_record(self, user: str, number: str, value: Any, reason: str) -> Any:
        """Re-enter the earlier record ``number`` of the current procedure; both values are logged.

        The run stays where it is; later instructions use the new value (go back with
        :meth:`go_back` to perform them again). Returns the value as recorded.
        """
        with self._changed:
            self._engine.require_idle()
            _require_reason(reason, "the record is corrected")
            frame = self._state.frame
            local = number.removeprefix(frame.prefix) if number.startswith(frame.prefix) else None
            instruction = frame.procedure.instruction(local) if local is not None and "/" not in local else None
            if not isinstance(instruction, RecordInstruction):
                raise OperatorActionError(f"{number} is not a record of {frame.procedure.id}")
            if instruction.name not in frame.env or number == frame.number():
                raise OperatorActionError(f"{number} has not been entered yet: enter it when the run gets there")
            converted, against, allowed = self._engine.automation.check_record(instruction, value)
            old = frame.env[instruction.name]
            frame.env[instruction.name] = converted
            corrected = RecordCorrected(
                name=instruction.name,
                old=old,
                value=converted,
                reason=reason,
                checked_against=against,
                allowed=allowed,
            )
            self._engine.emit(user, number, corrected)
            self._state.announce()
            return converted

    def mark_done(self, user: str) -> None:
        """Complete the current manual instruction."""
        with self._changed:
            instruction = self._engine.require_idle()
            if not isinstance(instruction, ManualInstruction):
                raise OperatorActionError(
                    f"{self._state.current_number()} is a {instruction.kind.value}, not a manual instruction"
                )
            frame = self._state.frame
            self._state.complete(user, frame.procedure.following(frame.position))

    def retry(self, user: str) -> None:
        """Perform a failed, halted (or interrupted) instruction again, as ``user``: a new attempt."""
        with self._changed:
            instruction = self._engine.require_idle()
            state = self._state
            number = state.current_number()
            if state.unknown or state.resend:
                raise OperatorActionError(self._engine.unknown_text())
            halted_here = state.statuses.get(state.frame.number()) is InstructionStatus.HALTED
            if not (state.failure or state.in_flight or halted_here):
                raise OperatorActionError(f"{number} has not failed or been halted")
            replan = self._engine.halted_motion()
            if replan is not None:
                raise OperatorActionError(replan.why_not_again())
            if state.unconfirmed(instruction):
                raise OperatorActionError(state.unconfirmed_text(number, instruction))
            self._engine.emit(user, number, Retry(after=state.failure or state.in_flight or state.halt_text()))
            state.clear_holds()
            self._engine.clear_halt()
            state.request = Request(user)
            self._changed.notify_all()

    def ask_again(self, user: str) -> None:
        """Send the command of unknown outcome again with its same key: the habitat answers its
        recorded outcome or joins it, and never runs it twice."""
        with self._changed:
            self._engine.require_idle()
            state = self._state
            key = self._engine.pending_key()
            if key is None:
                raise OperatorActionError(f"{state.current_number()} has no command of unknown outcome")
            after = state.unknown[1] if state.unknown else f"{key} in flight"
            self._engine.emit(user, state.current_number(), Retry(after=after, same_key=True, key=key))
            state.clear_holds()
            self._engine.clear_halt()
            state.resend = key
            state.request = Request(user)
            self._changed.notify_all()

    def resolve(self, user: str, outcome: Outcome | str, reason: str) -> None:
        """Record what became of the command of unknown outcome, as ``user`` found it on the robot.

        ``outcome`` is succeeded (the instruction completes) or failed (it fails: its on-failure
        step, or a failure hold); ``reason`` says what was checked.
        """
        try:
            found = Outcome(outcome)
        except ValueError:
            found = None
        if found not in (Outcome.SUCCEEDED, Outcome.FAILED):
            raise OperatorActionError(f"record succeeded or failed, not {outcome!r}")
        with self._changed:
            self._engine.require_idle()
            _require_reason(reason, "you record this outcome (what did you check?)")
            key = self._engine.pending_key()
            if key is None:
                raise OperatorActionError(f"{self._state.current_number()} has no command of unknown outcome")
            self._engine.clear_halt()
            self._state.resolve(user, key, found is Outcome.SUCCEEDED, reason)

    def skip(self, user: str, reason: str) -> None:
        """Pass over the current instruction without performing it; ``reason`` is required."""
        with self._changed:
            self._engine.require_idle()
            _require_reason(reason, "the instruction is skipped")
            self._engine.clear_halt()
            self._state.skip(user, reason)

    def go_back(self, user: str, number: str, reason: str) -> None:
        """Go back to the earlier instruction ``number`` of the current step; PAX continues from there."""
        with self._changed:
            self._engine.require_idle()
            _require_reason(reason, "the run goes back")
            state = self._state
            if state.unknown or state.resend:
                raise OperatorActionError(self._engine.unknown_text())
            frame = state.frame
            current = frame.number()
            local = number.removeprefix(frame.prefix) if number.startswith(frame.prefix) else ""
            items = frame.procedure.instructions
            position = next((n for n, i in enumerate(items) if i.number == local), None)
            here = items[frame.position].number
            if position is None or local.split(".")[0] != here.split(".")[0]:
                raise OperatorActionError(f"{number} is not an instruction of the current step (at {current})")
            if position >= frame.position:
                raise OperatorActionError(f"{number} is not before {current}")
            self._engine.clear_halt()
            state.go_back(user, position, reason)

    def replan(self, user: str) -> None:
        """After a halted motion, go back to the instruction of its step that planned it, as ``user``:
        the run plans it again from where the arm is and goes on from there (see After a halted motion)."""
        with self._changed:
            self._engine.require_idle()
            replan = self._engine.halted_motion()
            number = self._state.current_number()
            if replan is None:
                raise OperatorActionError(f"{number} is no halted motion to plan again")
            if replan.position is None:
                raise OperatorActionError(replan.why_not_again())  # no instruction of its step plans it
            self._engine.clear_halt()
            self._state.go_back(user, replan.position, replan.reason())

    def operator_command(self, user: str, system: str, command: str, args: dict[str, Any]) -> CommandResult:
        """Send a command an operator gave outside the procedure's instructions (a registration
        dragged in the 3D view), as ``user``, through the run's gateway like any command.

        Journaled COMMAND_SENT/COMMAND_RESULT without an instruction number, with the user, the
        arguments and its own key (``<run>/operator/<seq>``, executed at most once by the
        habitat), so the audit log attributes it; the run's position does not change. Its
        outcome is the gateway's (unknown stays unknown). Refused (OperatorActionError) when the
        run is not active, an instruction is being performed, or the run does not control its
        robot.
        """
        with self._lock:
            self._engine.require_active()
            if self._state.executing:  # one command at a time on the robot, as the procedure sends them
                raise OperatorActionError(f"{self._state.current_number()} is being performed; try when it is done")
            try:
                self._engine.may_send()
            except ControlLost as exc:
                raise OperatorActionError(str(exc)) from None
            sent = record_sent(self._engine, user, "operator", system, command, args)
        return send_recorded(self._engine, user, sent)

    def record_refusal(self, user: str, instruction: str | None, refused: ActionRefused) -> None:
        """Record an act of ``user`` refused before it reached the run (an observer's, a click on an
        instruction the run has left), so every refused act is on the record; nothing once the run ended."""
        with self._changed:
            if self._state.status is RunStatus.ACTIVE and not self._state.stopping:
                self._engine.emit(user, instruction, refused)

    # ---- guards -----------------------------------------------------------------------------
    def _check_number(self, number: str) -> None:
        head = number.split("/")[0]
        if self.procedure.instruction(head) is None:
            raise OperatorActionError(f"no instruction {number!r} in {self.procedure.id}")

    def is_hazardous(self, instruction: Instruction) -> bool:
        """Whether an instruction is a command that needs confirmation (marked so, or so in its SysRep)."""
        return self._engine.automation.is_hazardous(instruction)


def _cancel_data(answer: CancelResult | None) -> dict[str, Any] | None:
    return None if answer is None else {"stopped": answer.stopped, "message": answer.message}


def _require_reason(reason: str, what: str) -> None:
    if not reason.strip():
        raise OperatorActionError(f"say why {what}")
