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
    unconfirmed hazardous commands, breakpoints, failures and operator pauses, and carries on by
    itself as soon as the operator has completed, confirmed, retried, skipped or continued.

Operator actions (raise :class:`OperatorActionError` saying why when not applicable now)
    start, set_mode, pause, resume_automation, stop, set_breakpoint, clear_breakpoint,
    perform, step, confirm, enter, mark_done, retry, skip.

Failure
    A failed command, verify or wait (or an unbound variable) never counts as done: the run goes
    to the instruction's ``on-failure`` step if it has one, else holds with Hold.FAILURE and the
    reason until an operator retries or skips it.

Observation
    :meth:`add_listener` registers ``callback(event)`` for every :class:`~pride.events.Event`,
    called after the event is durably in the journal, on the thread that caused it, while the
    executive's lock is held: listeners must be quick, must not block, and must not call operator
    actions (hand events to a queue instead). :meth:`snapshot` returns an immutable
    :class:`Snapshot`; :meth:`wait_for` blocks until a snapshot meets a predicate.

Durability
    Every event goes to the journal (the audit log) before the run proceeds. :meth:`resume`
    rebuilds a run from its events (:mod:`pride.replay`): it continues after the last completed instruction, and an
    instruction that was in flight (a command sent, no result recorded) holds with Hold.IN_FLIGHT
    until an operator decides to retry (resend) or skip it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from pride.automation import Automation, Outcome
from pride.events import Event, EventKind, Journal
from pride.lint import CheckedProcedure
from pride.model import Instruction, ManualInstruction, RecordInstruction
from pride.replay import replay
from pride.run_state import Request, RunState
from pride.states import Hold, InstructionStatus, Mode, OperatorActionError, RunStatus, Snapshot
from pride.systems import CommandResult, SystemGateway, TelemetryValue

__all__ = ["Executive", "Hold", "InstructionStatus", "Mode", "OperatorActionError", "RunStatus", "Snapshot"]

log = logging.getLogger(__name__)


class Executive:
    """Runs one procedure; see the module docstring for the API contract."""

    def __init__(self, checked: CheckedProcedure, gateway: SystemGateway, journal: Journal, *, run_id: str,
                 mode: Mode = Mode.MANUAL) -> None:
        """Prepare a run (nothing happens until :meth:`start`).

        Args:
            checked: what to run, as :func:`pride.lint.check_procedure` checked it (with its
                SysReps and sub-procedures): a procedure with errors never gets this far.
            gateway: the systems (the PAX host shape, :mod:`pride.systems`).
            journal: where every event goes first (the audit log).
            run_id: the run's id in the journal.
            mode: the initial mode.
        """
        self.procedure = checked.procedure
        self.run_id = run_id
        self._checked = checked
        self._gateway = gateway
        self._journal = journal
        self._lock = threading.RLock()  # guards every field below and the run state
        self._changed = threading.Condition(self._lock)
        self._seq = 0
        self._listeners: list[Callable[[Event], None]] = []
        self._automation = Automation(gateway, checked, self._record)
        self._state = RunState(self.procedure, mode, emit=self._emit, notify=self._changed.notify_all,
                               hazardous=self._automation.is_hazardous)
        self._worker: threading.Thread | None = None
        gateway.add_listener(self._telemetry_callback)

    # ---- observation ------------------------------------------------------------------------
    def add_listener(self, callback: Callable[[Event], None]) -> None:
        """Call ``callback(event)`` for every event from now on (see the module docstring)."""
        with self._lock:
            self._listeners.append(callback)

    def remove_listener(self, callback: Callable[[Event], None]) -> None:
        with self._lock:
            self._listeners.remove(callback)

    def snapshot(self) -> Snapshot:
        """The run's state now."""
        with self._lock:
            state = self._state
            hold, reason = state.hold()
            current = state.current_number() if state.status is RunStatus.ACTIVE else None
            return Snapshot(
                run_id=self.run_id, procedure_id=self.procedure.id, status=state.status, mode=state.mode,
                current=current, hold=hold, reason=reason, executing=state.executing,
                statuses=dict(state.statuses), breakpoints=frozenset(state.breakpoints),
                variables=state.variables(), last_seq=self._seq, error=state.error,
            )

    def current_instruction(self) -> Instruction | None:
        """The instruction the run is at (in the innermost sub-procedure), or None when finished."""
        with self._lock:
            return self._state.frame.instruction if self._state.status is RunStatus.ACTIVE else None

    def wait_for(self, predicate: Callable[[Snapshot], bool], timeout: float | None = None) -> Snapshot | None:
        """Block until ``predicate(snapshot)`` holds; return that snapshot, or None on timeout."""
        deadline = None if timeout is None else time.monotonic() + timeout
        with self._changed:
            while True:
                snap = self.snapshot()
                if predicate(snap):
                    return snap
                remaining = None if deadline is None else deadline - time.monotonic()
                if remaining is not None and remaining <= 0:
                    return None
                self._changed.wait(remaining)

    def join(self, timeout: float | None = None) -> None:
        """Wait for PAX's thread to end (after the run completed or stopped)."""
        if self._worker is not None:
            self._worker.join(timeout)

    # ---- lifecycle --------------------------------------------------------------------------
    def start(self, user: str) -> None:
        """Begin the run (called once, by whoever launches it)."""
        with self._changed:
            state = self._state
            if state.status is not RunStatus.READY:
                raise OperatorActionError(f"run {self.run_id} was already started")
            state.status = RunStatus.ACTIVE
            procedure = self.procedure
            self._emit(EventKind.RUN_STARTED, user, None, procedure=procedure.id, title=procedure.title,
                       version=procedure.version, path=str(Path(procedure.path).resolve()), mode=state.mode.value,
                       steps=[{"number": s.number, "id": s.id, "title": s.title} for s in procedure.steps])
            state.arrive()
            self._launch()

    @classmethod
    def resume(cls, checked: CheckedProcedure, gateway: SystemGateway, journal: Journal, events: list[Event], user: str,
               *, mode: Mode | None = None) -> Executive:
        """Continue an interrupted run from its recorded events (see Durability above)."""
        procedure = checked.procedure
        if not events or events[0].kind is not EventKind.RUN_STARTED:
            raise OperatorActionError("the log holds no start of that run")
        if any(e.kind is EventKind.RUN_COMPLETED for e in events):
            raise OperatorActionError(f"run {events[0].run_id} is already completed")
        started = events[0]
        if started.data.get("procedure") != procedure.id:
            raise OperatorActionError(f"run {started.run_id} ran procedure {started.data.get('procedure')!r}, "
                                      f"not {procedure.id!r}")
        executive = cls(checked, gateway, journal, run_id=started.run_id, mode=Mode(started.data.get("mode", "manual")))
        with executive._changed:
            state = executive._state
            replayed = replay(procedure, events, checked.load, mode=state.mode, statuses=state.statuses)
            state.restore(replayed)
            executive._seq = replayed.seq
            if mode is not None:
                state.mode = mode
            state.status = RunStatus.ACTIVE
            executive._emit(EventKind.RUN_RESUMED, user, state.frame.number(), mode=state.mode.value,
                            in_flight=state.in_flight)
            if state.frame.instruction is None:
                state.advance(state.frame.position)
            else:
                state.statuses[state.frame.number()] = InstructionStatus.ACTIVE
            state.announce()
            executive._launch()
        return executive

    def _launch(self) -> None:
        self._worker = threading.Thread(target=self._pax_loop, name=f"pax-{self.run_id}", daemon=True)
        self._worker.start()

    # ---- operator actions -------------------------------------------------------------------
    def set_mode(self, user: str, mode: Mode) -> None:
        """Switch between manual and autonomous execution."""
        with self._changed:
            self._require_active()
            if mode is self._state.mode:
                return
            self._state.mode = mode
            self._emit(EventKind.MODE_CHANGED, user, self._state.current_number(), mode=mode.value)
            self._state.announce()

    def pause(self, user: str) -> None:
        """Stop automation after the instruction in progress (autonomous mode stays selected)."""
        with self._changed:
            self._require_active()
            if self._state.paused:
                return
            self._state.paused = True
            self._emit(EventKind.PAUSED, user, self._state.current_number())

    def resume_automation(self, user: str) -> None:
        """Let automation carry on after a pause or a breakpoint."""
        with self._changed:
            self._require_active()
            state = self._state
            if not (state.paused or state.at_breakpoint):
                raise OperatorActionError("automation is neither paused nor at a breakpoint")
            state.paused = state.at_breakpoint = False
            self._emit(EventKind.CONTINUED, user, state.current_number())
            state.announce()

    def stop(self, user: str, reason: str = "") -> None:
        """End the run now; a command in progress finishes and is recorded. The run can be resumed."""
        with self._changed:
            self._require_active()
            self._state.status = RunStatus.STOPPED
            self._automation.abort.set()
            self._emit(EventKind.RUN_STOPPED, user, self._state.current_number(), reason=reason)

    def set_breakpoint(self, user: str, number: str) -> None:
        """Make automation hold when it reaches instruction ``number``."""
        with self._changed:
            self._check_number(number)
            if number not in self._state.breakpoints:
                self._state.breakpoints.add(number)
                self._emit(EventKind.BREAKPOINT_SET, user, number)

    def clear_breakpoint(self, user: str, number: str) -> None:
        with self._changed:
            if number in self._state.breakpoints:
                self._state.breakpoints.discard(number)
                self._emit(EventKind.BREAKPOINT_CLEARED, user, number)

    def perform(self, user: str) -> None:
        """Perform the current instruction as ``user`` ("Send", "Check", "Start"); PAX carries it out."""
        self._request_perform(user, then_pause=False)

    def step(self, user: str) -> None:
        """Perform the current instruction, then hold automation at the next one."""
        self._request_perform(user, then_pause=self._state.mode is Mode.AUTONOMOUS)

    def _request_perform(self, user: str, *, then_pause: bool) -> None:
        with self._changed:
            instruction = self._require_idle()
            state = self._state
            number = state.current_number()
            if isinstance(instruction, (RecordInstruction, ManualInstruction)):
                todo = "enter a value" if isinstance(instruction, RecordInstruction) else "mark it done"
                raise OperatorActionError(f"{number} is a {instruction.kind.value}: {todo}")
            if state.failure or state.in_flight:
                raise OperatorActionError(f"{number} failed or was interrupted: retry or skip it")
            if state.unconfirmed(instruction):
                raise OperatorActionError(f"{number} is a hazardous command: confirm it first")
            state.request = Request(user, then_pause)
            state.at_breakpoint = False
            self._changed.notify_all()

    def confirm(self, user: str) -> None:
        """Confirm the current hazardous command (needed before it is sent, in either mode)."""
        with self._changed:
            instruction = self._require_idle()
            if not self.is_hazardous(instruction):
                raise OperatorActionError(f"{self._state.current_number()} is not a hazardous command")
            self._state.confirmed = True
            self._emit(EventKind.CONFIRMATION, user, self._state.current_number(), command=instruction.describe())
            self._state.announce()

    def enter(self, user: str, value: Any) -> Any:
        """Answer the current record; returns the value as recorded (converted to its type)."""
        with self._changed:
            instruction = self._require_idle()
            if not isinstance(instruction, RecordInstruction):
                raise OperatorActionError(f"{self._state.current_number()} is a {instruction.kind.value}, not a record")
            try:
                converted = instruction.check(value)
            except ValueError as exc:
                raise OperatorActionError(str(exc)) from None
            frame = self._state.frame
            frame.env[instruction.name] = converted
            self._emit(EventKind.OPERATOR_INPUT, user, frame.number(), name=instruction.name, value=converted)
            self._state.complete(user, frame.procedure.following(frame.position))
            return converted

    def mark_done(self, user: str) -> None:
        """Complete the current manual instruction."""
        with self._changed:
            instruction = self._require_idle()
            if not isinstance(instruction, ManualInstruction):
                raise OperatorActionError(f"{self._state.current_number()} is a {instruction.kind.value}, "
                                          "not a manual instruction")
            frame = self._state.frame
            self._state.complete(user, frame.procedure.following(frame.position))

    def retry(self, user: str) -> None:
        """Perform a failed (or interrupted) instruction again, as ``user``."""
        with self._changed:
            instruction = self._require_idle()
            state = self._state
            if not (state.failure or state.in_flight):
                raise OperatorActionError(f"{state.current_number()} has not failed")
            if state.unconfirmed(instruction):
                raise OperatorActionError(f"{state.current_number()} is a hazardous command: confirm it first")
            self._emit(EventKind.RETRY, user, state.current_number(), after=state.failure or state.in_flight)
            state.failure = state.in_flight = None
            state.request = Request(user)
            self._changed.notify_all()

    def skip(self, user: str, reason: str) -> None:
        """Pass over the current instruction without performing it; ``reason`` is required."""
        with self._changed:
            self._require_idle()
            if not reason.strip():
                raise OperatorActionError("say why the instruction is skipped")
            self._state.skip(user, reason)

    def operator_command(self, user: str, system: str, command: str, args: dict[str, Any]) -> CommandResult:
        """Send a command an operator gave outside the procedure's instructions (a registration
        dragged in the 3D view), as ``user``, through the run's gateway like any command.

        Journaled COMMAND_SENT/COMMAND_RESULT without an instruction number, with the user, the
        arguments and its own key (``<run>/operator/<n>``), so the audit log attributes it; the
        run's position does not change. Refused when the run is not active or an instruction is
        being performed (OperatorActionError).
        """
        with self._lock:
            self._require_active()
            if self._state.executing:  # one command at a time on the robot, as the procedure sends them
                raise OperatorActionError(f"{self._state.current_number()} is being performed; try when it is done")
            key = f"{self.run_id}/operator/{self._seq + 1}"
            about = {"system": system, "command": command, "args": dict(args), "key": key, "ad_hoc": True}
            self._emit(EventKind.COMMAND_SENT, user, None, **about, hazardous=False)
        try:
            result: CommandResult = self._gateway.execute(system, command, args)
        except Exception as exc:  # refused before sending (bad argument, unknown command)
            result = CommandResult(False, f"not sent: {type(exc).__name__}: {exc}")
        self._record(EventKind.COMMAND_RESULT, user, None, **about, success=result.success,
                     message=result.message, values=dict(result.values))
        return result

    # ---- guards -----------------------------------------------------------------------------
    def _require_active(self) -> None:
        if self._state.status is not RunStatus.ACTIVE:
            raise OperatorActionError(f"run {self.run_id} is {self._state.status.value}")

    def _require_idle(self) -> Instruction:
        self._require_active()
        instruction = self._state.frame.instruction
        if instruction is None:
            raise OperatorActionError("the run has no current instruction")
        if self._state.executing or self._state.request is not None:
            raise OperatorActionError(f"{self._state.current_number()} is being performed; wait for it to finish")
        return instruction

    def _check_number(self, number: str) -> None:
        head = number.split("/")[0]
        if self.procedure.instruction(head) is None:
            raise OperatorActionError(f"no instruction {number!r} in {self.procedure.id}")

    def is_hazardous(self, instruction: Instruction) -> bool:
        """Whether an instruction is a command that needs confirmation (marked so, or so in its SysRep)."""
        return self._automation.is_hazardous(instruction)

    # ---- events -----------------------------------------------------------------------------
    def _emit(self, kind: EventKind, actor: str, instruction: str | None, /, **data: Any) -> Event:
        """Record an event (the lock is held): durably first, then wake waiters and tell listeners."""
        self._seq += 1
        event = Event(self.run_id, self._seq, kind, actor, instruction, data)
        self._journal.append(event)  # durable first: if this raises, the action does not happen
        self._changed.notify_all()  # every event is a change someone may be waiting for
        for listener in list(self._listeners):
            try:
                listener(event)
            except Exception:  # an observer's bug must not stop a robot mid-procedure
                log.exception("event listener %r failed on %s", listener, kind.value)
        return event

    def _record(self, kind: EventKind, actor: str, instruction: str | None, /, **data: Any) -> None:
        """Emit from PAX's thread while it does not hold the lock (automation's callback)."""
        with self._lock:
            self._emit(kind, actor, instruction, **data)

    # ---- PAX's thread -----------------------------------------------------------------------
    def _pax_loop(self) -> None:
        state = self._state
        try:
            while True:
                with self._changed:
                    job = state.next_job()
                    while job is None and state.status is RunStatus.ACTIVE:
                        self._changed.wait()
                        job = state.next_job()
                    if job is None:
                        return
                    number = job.frame.number()
                    state.executing = True
                    state.request = None
                    state.statuses[number] = InstructionStatus.EXECUTING
                    self._emit(EventKind.INSTRUCTION_STARTED, job.actor, number,
                               instruction_kind=job.instruction.kind.value, text=job.instruction.describe())
                try:
                    outcome = self._automation.carry_out(job.frame.env, job.frame.procedure, job.instruction, number,
                                                         job.actor)
                except KeyError as exc:
                    outcome = Outcome(False, str(exc.args[0]) if exc.args else str(exc))
                except Exception as exc:  # a gateway error is a failed instruction, never a success
                    log.exception("%s failed", number)
                    outcome = Outcome(False, f"{type(exc).__name__}: {exc}")
                with self._changed:
                    state.executing = False
                    state.finish(job, number, outcome)
                    if job.then_pause and state.status is RunStatus.ACTIVE and not state.paused:
                        state.paused = True
                        self._emit(EventKind.PAUSED, job.actor, state.current_number(), after_step=number)
                    self._changed.notify_all()
        except Exception as exc:  # the journal failed: nothing may run unrecorded
            log.exception("run %s stopped: %s", self.run_id, exc)
            with self._changed:
                state.error = f"{type(exc).__name__}: {exc}"
                state.status = RunStatus.STOPPED
                state.executing = False
                self._automation.abort.set()
                self._changed.notify_all()

    def _telemetry_callback(self, sysrep_id: str, item_id: str, value: TelemetryValue) -> None:
        """Called by the gateway on its own thread when telemetry changes: wake any watcher."""
        self._automation.telemetry_changed.set()
