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
    rebuilds a run from its events: it continues after the last completed instruction, and an
    instruction that was in flight (a command sent, no result recorded) holds with Hold.IN_FLIGHT
    until an operator decides to retry (resend) or skip it.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from pride.automation import Automation, Outcome
from pride.diagnostics import ProcedureError
from pride.events import PAX, Event, EventKind, Journal
from pride.lint import lint_procedure
from pride.model import CallInstruction, Instruction, ManualInstruction, Procedure, RecordInstruction
from pride.parser import load_procedure
from pride.states import Hold, InstructionStatus, Mode, OperatorActionError, RunStatus, Snapshot
from pride.sysrep import SysRep
from pride.systems import SystemGateway

__all__ = ["Executive", "Hold", "InstructionStatus", "Mode", "OperatorActionError", "RunStatus", "Snapshot"]

log = logging.getLogger(__name__)

_END = "end"


@dataclass
class _Frame:
    """One procedure being run: the main one, or a sub-procedure entered by a call."""

    procedure: Procedure
    prefix: str  # "" for the main procedure, "3.2/" inside the sub-procedure called by 3.2
    position: int
    env: dict[str, Any] = field(default_factory=dict)

    @property
    def instruction(self) -> Instruction | None:
        items = self.procedure.instructions
        return items[self.position] if self.position < len(items) else None

    def number(self, position: int | None = None) -> str:
        position = self.position if position is None else position
        items = self.procedure.instructions
        return self.prefix + (items[position].number if position < len(items) else _END)


@dataclass
class _Request:
    """An operator asked PAX's thread to perform the current instruction on their behalf."""

    actor: str
    then_pause: bool = False


class Executive:
    """Runs one procedure; see the module docstring for the API contract."""

    def __init__(
        self,
        procedure: Procedure,
        gateway: SystemGateway,
        journal: Journal,
        *,
        run_id: str,
        mode: Mode = Mode.MANUAL,
        sysreps: Mapping[str, SysRep] | None = None,
        load: Callable[[str], Procedure] = load_procedure,
    ) -> None:
        """Prepare a run (nothing happens until :meth:`start`).

        Args:
            procedure: what to run.
            gateway: the systems (the PAX host shape, :mod:`pride.systems`).
            journal: where every event goes first (the audit log).
            run_id: the run's id in the journal.
            mode: the initial mode.
            sysreps: the SysReps to check the procedure against (argument types, hazardous
                flags); when given, a procedure with lint errors is refused.
            load: how a called sub-procedure file is loaded.

        Raises:
            ProcedureError: the procedure has errors against ``sysreps``.
        """
        if sysreps is not None:
            problems = lint_procedure(procedure, sysreps)
            if problems:
                raise ProcedureError(problems)  # no procedure with errors starts
        self.procedure = procedure
        self.run_id = run_id
        self._journal = journal
        self._load = load
        self._lock = threading.RLock()  # guards every field below
        self._changed = threading.Condition(self._lock)
        self._status = RunStatus.READY
        self._mode = mode
        self._frames: list[_Frame] = [_Frame(procedure, "", 0)]
        self._statuses: dict[str, InstructionStatus] = {i.number: InstructionStatus.PENDING for i in procedure.instructions}
        self._breakpoints: set[str] = set()
        self._paused = False
        self._at_breakpoint = False
        self._confirmed = False
        self._failure: str | None = None
        self._in_flight: str | None = None
        self._request: _Request | None = None
        self._executing = False
        self._announced: tuple[str, Hold] | None = None
        self._seq = 0
        self._error: str | None = None
        self._listeners: list[Callable[[Event], None]] = []
        self._automation = Automation(gateway, sysreps or {}, load, self._record)
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
            hold, reason = self._hold()
            frame = self._frames[-1]
            current = frame.number() if self._status is RunStatus.ACTIVE and frame.instruction else None
            return Snapshot(
                run_id=self.run_id, procedure_id=self.procedure.id, status=self._status, mode=self._mode,
                current=current, hold=hold, reason=reason, executing=self._executing,
                statuses=dict(self._statuses), breakpoints=frozenset(self._breakpoints),
                variables={k: v for f in self._frames for k, v in f.env.items()}, last_seq=self._seq,
                error=self._error,
            )

    def current_instruction(self) -> Instruction | None:
        """The instruction the run is at (in the innermost sub-procedure), or None when finished."""
        with self._lock:
            return self._frames[-1].instruction if self._status is RunStatus.ACTIVE else None

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
            if self._status is not RunStatus.READY:
                raise OperatorActionError(f"run {self.run_id} was already started")
            self._status = RunStatus.ACTIVE
            self._emit(EventKind.RUN_STARTED, user, None, procedure=self.procedure.id, title=self.procedure.title,
                       version=self.procedure.version, path=str(Path(self.procedure.path).resolve()), mode=self._mode.value,
                       steps=[{"number": s.number, "id": s.id, "title": s.title} for s in self.procedure.steps])
            self._arrive()
            self._launch()

    @classmethod
    def resume(
        cls,
        procedure: Procedure,
        gateway: SystemGateway,
        journal: Journal,
        events: list[Event],
        user: str,
        *,
        mode: Mode | None = None,
        sysreps: Mapping[str, SysRep] | None = None,
        load: Callable[[str], Procedure] = load_procedure,
    ) -> Executive:
        """Continue an interrupted run from its recorded events (see Durability above)."""
        if not events or events[0].kind is not EventKind.RUN_STARTED:
            raise OperatorActionError("the log holds no start of that run")
        if any(e.kind is EventKind.RUN_COMPLETED for e in events):
            raise OperatorActionError(f"run {events[0].run_id} is already completed")
        started = events[0]
        if started.data.get("procedure") != procedure.id:
            raise OperatorActionError(f"run {started.run_id} ran procedure {started.data.get('procedure')!r}, not {procedure.id!r}")
        executive = cls(procedure, gateway, journal, run_id=started.run_id,
                        mode=Mode(started.data.get("mode", "manual")), sysreps=sysreps, load=load)
        with executive._changed:
            executive._replay(events)
            if mode is not None:
                executive._mode = mode
            executive._status = RunStatus.ACTIVE
            executive._emit(EventKind.RUN_RESUMED, user, executive._frames[-1].number(), mode=executive._mode.value,
                            in_flight=executive._in_flight)
            if executive._frames[-1].instruction is None:
                executive._advance(executive._frames[-1].position)
            else:
                executive._statuses[executive._frames[-1].number()] = InstructionStatus.ACTIVE
            executive._announce()
            executive._launch()
        return executive

    def _replay(self, events: list[Event]) -> None:
        cursor = self.procedure.instructions[0].number
        envs: dict[str, dict[str, Any]] = {}
        started: str | None = None
        sent: str | None = None
        for event in events:
            number = event.instruction
            prefix = number.rsplit("/", 1)[0] + "/" if number and "/" in number else ""
            kind = event.kind
            if kind in (EventKind.MODE_CHANGED, EventKind.RUN_RESUMED):
                self._mode = Mode(event.data["mode"])
            elif kind is EventKind.BREAKPOINT_SET:
                self._breakpoints.add(number)
            elif kind is EventKind.BREAKPOINT_CLEARED:
                self._breakpoints.discard(number)
            elif kind is EventKind.OPERATOR_INPUT:
                envs.setdefault(prefix, {})[event.data["name"]] = event.data["value"]
            elif kind is EventKind.COMMAND_SENT:
                sent = number
            elif kind is EventKind.COMMAND_RESULT:
                sent = None
                if event.data.get("result"):
                    envs.setdefault(prefix, {})[event.data["result"]] = _result_values(event.data)
            elif kind is EventKind.CALL_ENTERED:
                envs[number + "/"] = dict(event.data.get("inputs", {}))
            elif kind is EventKind.INSTRUCTION_STARTED:
                started = number
                self._statuses[number] = InstructionStatus.EXECUTING
            elif kind in (EventKind.INSTRUCTION_COMPLETED, EventKind.INSTRUCTION_FAILED, EventKind.INSTRUCTION_SKIPPED):
                self._statuses[number] = {
                    EventKind.INSTRUCTION_COMPLETED: InstructionStatus.COMPLETED,
                    EventKind.INSTRUCTION_FAILED: InstructionStatus.FAILED,
                    EventKind.INSTRUCTION_SKIPPED: InstructionStatus.SKIPPED,
                }[kind]
                cursor = event.data["next"]
                started = sent = None
                self._failure = event.data.get("reason") if kind is EventKind.INSTRUCTION_FAILED and cursor == number else None
            self._seq = event.seq
        self._frames = self._frames_at(cursor, envs)
        if started is not None and started == cursor and sent is not None:
            self._in_flight = (f"{cursor} was in flight when the runner stopped: the command was sent and no "
                               "result was recorded. Check the system, then retry (resend) or skip it.")

    def _frames_at(self, cursor: str, envs: dict[str, dict[str, Any]]) -> list[_Frame]:
        frames: list[_Frame] = []
        procedure = self.procedure
        prefix = ""
        parts = cursor.split("/")
        for depth, part in enumerate(parts):
            items = procedure.instructions
            position = len(items) if part == _END else next(n for n, i in enumerate(items) if i.number == part)
            frames.append(_Frame(procedure, prefix, position, dict(envs.get(prefix, {}))))
            if depth + 1 < len(parts):
                call = items[position]
                assert isinstance(call, CallInstruction)
                procedure = self._load(call.resolved_path)
                prefix = f"{prefix}{part}/"
        return frames

    def _launch(self) -> None:
        self._worker = threading.Thread(target=self._pax_loop, name=f"pax-{self.run_id}", daemon=True)
        self._worker.start()

    # ---- operator actions -------------------------------------------------------------------
    def set_mode(self, user: str, mode: Mode) -> None:
        """Switch between manual and autonomous execution."""
        with self._changed:
            self._require_active()
            if mode is self._mode:
                return
            self._mode = mode
            self._emit(EventKind.MODE_CHANGED, user, self._current_number(), mode=mode.value)
            self._announce()

    def pause(self, user: str) -> None:
        """Stop automation after the instruction in progress (autonomous mode stays selected)."""
        with self._changed:
            self._require_active()
            if self._paused:
                return
            self._paused = True
            self._emit(EventKind.PAUSED, user, self._current_number())

    def resume_automation(self, user: str) -> None:
        """Let automation carry on after a pause or a breakpoint."""
        with self._changed:
            self._require_active()
            if not (self._paused or self._at_breakpoint):
                raise OperatorActionError("automation is neither paused nor at a breakpoint")
            self._paused = self._at_breakpoint = False
            self._emit(EventKind.CONTINUED, user, self._current_number())
            self._announce()

    def stop(self, user: str, reason: str = "") -> None:
        """End the run now; a command in progress finishes and is recorded. The run can be resumed."""
        with self._changed:
            self._require_active()
            self._status = RunStatus.STOPPED
            self._automation.abort.set()
            self._emit(EventKind.RUN_STOPPED, user, self._current_number(), reason=reason)

    def set_breakpoint(self, user: str, number: str) -> None:
        """Make automation hold when it reaches instruction ``number``."""
        with self._changed:
            self._check_number(number)
            if number not in self._breakpoints:
                self._breakpoints.add(number)
                self._emit(EventKind.BREAKPOINT_SET, user, number)

    def clear_breakpoint(self, user: str, number: str) -> None:
        with self._changed:
            if number in self._breakpoints:
                self._breakpoints.discard(number)
                self._emit(EventKind.BREAKPOINT_CLEARED, user, number)

    def perform(self, user: str) -> None:
        """Perform the current instruction as ``user`` ("Send", "Check", "Start"); PAX carries it out."""
        self._request_perform(user, then_pause=False)

    def step(self, user: str) -> None:
        """Perform the current instruction, then hold automation at the next one."""
        self._request_perform(user, then_pause=self._mode is Mode.AUTONOMOUS)

    def _request_perform(self, user: str, *, then_pause: bool) -> None:
        with self._changed:
            instruction = self._require_idle()
            if isinstance(instruction, (RecordInstruction, ManualInstruction)):
                raise OperatorActionError(f"{self._current_number()} is a {instruction.kind.value}: "
                                          f"{'enter a value' if isinstance(instruction, RecordInstruction) else 'mark it done'}")
            if self._failure or self._in_flight:
                raise OperatorActionError(f"{self._current_number()} failed or was interrupted: retry or skip it")
            if self.is_hazardous(instruction) and not self._confirmed:
                raise OperatorActionError(f"{self._current_number()} is a hazardous command: confirm it first")
            self._request = _Request(user, then_pause)
            self._at_breakpoint = False
            self._changed.notify_all()

    def confirm(self, user: str) -> None:
        """Confirm the current hazardous command (needed before it is sent, in either mode)."""
        with self._changed:
            instruction = self._require_idle()
            if not self.is_hazardous(instruction):
                raise OperatorActionError(f"{self._current_number()} is not a hazardous command")
            self._confirmed = True
            self._emit(EventKind.CONFIRMATION, user, self._current_number(), command=instruction.describe())
            self._announce()

    def enter(self, user: str, value: Any) -> Any:
        """Answer the current record; returns the value as recorded (converted to its type)."""
        with self._changed:
            instruction = self._require_idle()
            if not isinstance(instruction, RecordInstruction):
                raise OperatorActionError(f"{self._current_number()} is a {instruction.kind.value}, not a record")
            try:
                converted = instruction.check(value)
            except ValueError as exc:
                raise OperatorActionError(str(exc)) from None
            frame = self._frames[-1]
            frame.env[instruction.name] = converted
            self._emit(EventKind.OPERATOR_INPUT, user, frame.number(), name=instruction.name, value=converted)
            self._complete(user, frame.procedure.following(frame.position))
            return converted

    def mark_done(self, user: str) -> None:
        """Complete the current manual instruction."""
        with self._changed:
            instruction = self._require_idle()
            if not isinstance(instruction, ManualInstruction):
                raise OperatorActionError(f"{self._current_number()} is a {instruction.kind.value}, not a manual instruction")
            self._complete(user, self._frames[-1].procedure.following(self._frames[-1].position))

    def retry(self, user: str) -> None:
        """Perform a failed (or interrupted) instruction again, as ``user``."""
        with self._changed:
            instruction = self._require_idle()
            if not (self._failure or self._in_flight):
                raise OperatorActionError(f"{self._current_number()} has not failed")
            if self.is_hazardous(instruction) and not self._confirmed:
                raise OperatorActionError(f"{self._current_number()} is a hazardous command: confirm it first")
            self._emit(EventKind.RETRY, user, self._current_number(), after=self._failure or self._in_flight)
            self._failure = self._in_flight = None
            self._request = _Request(user)
            self._changed.notify_all()

    def skip(self, user: str, reason: str) -> None:
        """Pass over the current instruction without performing it; ``reason`` is required."""
        with self._changed:
            self._require_idle()
            if not reason.strip():
                raise OperatorActionError("say why the instruction is skipped")
            frame = self._frames[-1]
            number = frame.number()
            self._failure = self._in_flight = None
            self._statuses[number] = InstructionStatus.SKIPPED
            following = frame.procedure.following(frame.position)
            self._emit(EventKind.INSTRUCTION_SKIPPED, user, number, reason=reason, next=self._next_number(following))
            self._advance(following)

    # ---- guards -----------------------------------------------------------------------------
    def _require_active(self) -> None:
        if self._status is not RunStatus.ACTIVE:
            raise OperatorActionError(f"run {self.run_id} is {self._status.value}")

    def _require_idle(self) -> Instruction:
        self._require_active()
        instruction = self._frames[-1].instruction
        if instruction is None:
            raise OperatorActionError("the run has no current instruction")
        if self._executing or self._request is not None:
            raise OperatorActionError(f"{self._current_number()} is being performed; wait for it to finish")
        return instruction

    def _check_number(self, number: str) -> None:
        head = number.split("/")[0]
        if self.procedure.instruction(head) is None:
            raise OperatorActionError(f"no instruction {number!r} in {self.procedure.id}")

    def _current_number(self) -> str | None:
        frame = self._frames[-1]
        return frame.number() if frame.instruction is not None else None

    def is_hazardous(self, instruction: Instruction) -> bool:
        """Whether an instruction is a command that needs confirmation (marked so, or so in its SysRep)."""
        return self._automation.is_hazardous(instruction)

    # ---- state (called with the lock held) ---------------------------------------------------
    def _hold(self) -> tuple[Hold | None, str]:
        instruction = self._frames[-1].instruction
        if self._status is not RunStatus.ACTIVE or instruction is None or self._executing or self._request:
            return None, ""
        number = self._current_number()
        if self._in_flight:
            return Hold.IN_FLIGHT, self._in_flight
        if self._failure:
            return Hold.FAILURE, f"{number} failed: {self._failure}"
        if isinstance(instruction, RecordInstruction):
            return Hold.OPERATOR_INPUT, f"{number}: {instruction.text}"
        if isinstance(instruction, ManualInstruction):
            return Hold.OPERATOR_ACTION, f"{number}: {instruction.text}"
        unconfirmed = self.is_hazardous(instruction) and not self._confirmed
        if self._mode is Mode.MANUAL:
            if unconfirmed:
                return Hold.CONFIRMATION, f"{number} is hazardous; confirm, then send: {instruction.describe()}"
            return Hold.MANUAL_MODE, f"{number}: {instruction.describe()}"
        if self._at_breakpoint:
            return Hold.BREAKPOINT, f"breakpoint at {number}"
        if self._paused:
            return Hold.PAUSED, f"automation paused at {number}"
        if not instruction.automatable:
            return Hold.NOT_AUTOMATABLE, f"{number} must be performed by an operator: {instruction.describe()}"
        if unconfirmed:
            return Hold.CONFIRMATION, f"{number} is hazardous; confirm to send: {instruction.describe()}"
        return None, ""

    def _announce(self) -> None:
        """Record once per instruction and reason that automation waits for an operator."""
        self._changed.notify_all()
        hold, reason = self._hold()
        if self._mode is not Mode.AUTONOMOUS or hold in (None, Hold.PAUSED, Hold.BREAKPOINT, Hold.MANUAL_MODE):
            return
        key = (self._current_number() or "", hold)
        if key != self._announced:
            self._announced = key
            self._emit(EventKind.AWAITING_OPERATOR, PAX, self._current_number(), hold=hold.value, reason=reason)

    def _arrive(self) -> None:
        """Make the frame's position the current instruction."""
        self._confirmed = False
        self._failure = None
        number = self._current_number()
        if number is None:
            return
        self._statuses[number] = InstructionStatus.ACTIVE
        if self._mode is Mode.AUTONOMOUS and number in self._breakpoints:
            self._at_breakpoint = True
            self._emit(EventKind.BREAKPOINT_HIT, PAX, number)
        self._announce()

    def _next_number(self, position: int) -> str:
        return self._frames[-1].number(position)

    def _complete(self, actor: str, position: int, **data: Any) -> None:
        frame = self._frames[-1]
        number = frame.number()
        self._statuses[number] = InstructionStatus.COMPLETED
        self._emit(EventKind.INSTRUCTION_COMPLETED, actor, number, next=self._next_number(position), **data)
        self._advance(position)

    def _advance(self, position: int) -> None:
        """Move to ``position`` in the innermost frame; finish sub-procedures and the run at their end."""
        frame = self._frames[-1]
        frame.position = position
        while frame.instruction is None:
            if len(self._frames) == 1:
                self._status = RunStatus.COMPLETED
                self._emit(EventKind.RUN_COMPLETED, PAX, None)
                self._changed.notify_all()
                return
            self._frames.pop()
            frame = self._frames[-1]
            number = frame.number()
            self._statuses[number] = InstructionStatus.COMPLETED
            frame.position = frame.procedure.following(frame.position)
            self._emit(EventKind.INSTRUCTION_COMPLETED, PAX, number, next=frame.number())
        self._arrive()

    def _position_of(self, frame: _Frame, step_ref: str) -> int:
        step = frame.procedure.step(step_ref)
        if step is None:  # lint rejects this; a procedure that skipped lint still must not run on
            raise KeyError(f"no step {step_ref!r}")
        first = step.instructions[0].number
        return next(n for n, i in enumerate(frame.procedure.instructions) if i.number == first)

    def _emit(self, kind: EventKind, actor: str, instruction: str | None, **data: Any) -> Event:
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

    def _record(self, kind: EventKind, actor: str, instruction: str | None, **data: Any) -> None:
        """Emit from PAX's thread while it does not hold the lock (automation's callback)."""
        with self._lock:
            self._emit(kind, actor, instruction, **data)

    # ---- PAX's thread -----------------------------------------------------------------------
    def _pax_loop(self) -> None:
        try:
            while True:
                with self._changed:
                    job = self._next_job()
                    while job is None and self._status is RunStatus.ACTIVE:
                        self._changed.wait()
                        job = self._next_job()
                    if job is None:
                        return
                    frame, instruction, actor, then_pause = job
                    number = frame.number()
                    self._executing = True
                    self._request = None
                    self._statuses[number] = InstructionStatus.EXECUTING
                    self._emit(EventKind.INSTRUCTION_STARTED, actor, number, instruction_kind=instruction.kind.value,
                               text=instruction.describe())
                    self._changed.notify_all()
                try:
                    outcome = self._automation.carry_out(frame.env, frame.procedure, instruction, number, actor)
                except KeyError as exc:
                    outcome = Outcome(False, str(exc.args[0]) if exc.args else str(exc))
                except Exception as exc:  # a gateway error is a failed instruction, never a success
                    log.exception("%s failed", number)
                    outcome = Outcome(False, f"{type(exc).__name__}: {exc}")
                with self._changed:
                    self._executing = False
                    self._finish(frame, instruction, number, actor, outcome)
                    if then_pause and self._status is RunStatus.ACTIVE and not self._paused:
                        self._paused = True
                        self._emit(EventKind.PAUSED, actor, self._current_number(), after_step=number)
                    self._changed.notify_all()
        except Exception as exc:  # the journal failed: nothing may run unrecorded
            log.exception("run %s stopped: %s", self.run_id, exc)
            with self._changed:
                self._error = f"{type(exc).__name__}: {exc}"
                self._status = RunStatus.STOPPED
                self._executing = False
                self._automation.abort.set()
                self._changed.notify_all()

    def _next_job(self) -> tuple[_Frame, Instruction, str, bool] | None:
        if self._status is not RunStatus.ACTIVE or self._executing:
            return None
        frame = self._frames[-1]
        instruction = frame.instruction
        if instruction is None:
            return None
        if self._request is not None:
            return frame, instruction, self._request.actor, self._request.then_pause
        if self._hold()[0] is None:
            return frame, instruction, PAX, False
        return None

    def _finish(self, frame: _Frame, instruction: Instruction, number: str, actor: str, outcome: Outcome) -> None:
        if outcome.result is not None:
            name, values = outcome.result
            frame.env[name] = values
        if self._status is not RunStatus.ACTIVE:
            # stopped meanwhile: record how it ended so a resume knows, but go nowhere. A failure
            # (often the stop itself ending a wait) is redone on resume, never branched from; a
            # sub-procedure that was about to start simply starts again.
            if outcome.enter is not None:
                return
            self._statuses[number] = InstructionStatus.COMPLETED if outcome.ok else InstructionStatus.FAILED
            if outcome.ok:
                next_number = frame.number(self._target(frame, instruction, outcome))
                self._emit(EventKind.INSTRUCTION_COMPLETED, actor, number, next=next_number)
            else:
                self._emit(EventKind.INSTRUCTION_FAILED, actor, number, reason=outcome.reason, next=number)
            return
        if outcome.ok:
            if outcome.enter is not None:
                callee, inputs = outcome.enter
                self._frames.append(_Frame(callee, f"{number}/", 0, dict(inputs)))
                self._emit(EventKind.CALL_ENTERED, actor, number, procedure=callee.id, inputs=dict(inputs))
                self._advance(0)
                return
            went = {"went_to": outcome.goto} if outcome.goto else {}
            self._complete(actor, self._target(frame, instruction, outcome), **went)
            return
        self._statuses[number] = InstructionStatus.FAILED
        target = self._target(frame, instruction, outcome)
        if target is not None:
            self._emit(EventKind.INSTRUCTION_FAILED, actor, number, reason=outcome.reason, next=frame.number(target),
                       branch=getattr(instruction, "on_failure", None))
            self._advance(target)
            return
        self._failure = outcome.reason
        self._emit(EventKind.INSTRUCTION_FAILED, actor, number, reason=outcome.reason, next=number)
        self._announce()

    def _target(self, frame: _Frame, instruction: Instruction, outcome: Outcome) -> int | None:
        """Where the run goes after the outcome; None means hold at a failure."""
        if outcome.ok:
            return self._position_of(frame, outcome.goto) if outcome.goto else frame.procedure.following(frame.position)
        on_failure = getattr(instruction, "on_failure", None)
        return self._position_of(frame, on_failure) if on_failure else None

    def _telemetry_callback(self, sysrep_id: str, item_id: str, value: Any) -> None:
        """Called by the gateway on its own thread when telemetry changes: wake any watcher."""
        self._automation.telemetry_changed.set()


def _result_values(data: dict[str, Any]) -> dict[str, Any]:
    return {"success": data.get("success"), "message": data.get("message", ""), **(data.get("values") or {})}
