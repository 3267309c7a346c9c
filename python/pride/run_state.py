"""Where one run is and what holds it, and how it moves from instruction to instruction.

The executive (:mod:`pride.executive`) owns one :class:`RunState` and touches it only with its
lock held; it decides *who* may act and *when* (operators, PAX's thread). This module holds the
state and the moves: arriving at an instruction, completing it, following an outcome to the next
one, entering and leaving sub-procedures, and which hold applies now. Every move records its
event through the executive's ``emit`` (the journal first) as it makes it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from pride.automation import Outcome
from pride.events import PAX, Event, EventKind
from pride.frames import Frame, position_of
from pride.model import (
    CommandInstruction,
    Instruction,
    ManualInstruction,
    Procedure,
    RecordInstruction,
    VerifyInstruction,
    WaitInstruction,
)
from pride.replay import Replayed
from pride.states import Hold, InstructionStatus, Mode, RunStatus

__all__ = ["Emit", "Job", "Request", "RunState"]


class Emit(Protocol):
    """The executive's ``_emit``: records an event durably, then tells observers."""

    def __call__(self, kind: EventKind, actor: str, instruction: str | None, /, **data: Any) -> Event: ...


@dataclass(frozen=True)
class Request:
    """An operator asked PAX's thread to perform the current instruction on their behalf."""

    actor: str
    then_pause: bool = False


@dataclass(frozen=True)
class Job:
    """An instruction PAX's thread is to perform now, and for whom."""

    frame: Frame
    instruction: Instruction
    actor: str
    then_pause: bool


def _on_failure(instruction: Instruction) -> str | None:
    if isinstance(instruction, (CommandInstruction, VerifyInstruction, WaitInstruction)):
        return instruction.on_failure
    return None


def _onward(frame: Frame, outcome: Outcome) -> int:
    """Where a successful outcome leads: the step it went to, or the instruction that follows."""
    return position_of(frame.procedure, outcome.goto) if outcome.goto else frame.procedure.following(frame.position)


class RunState:
    """The state of one run; see the module docstring. Fields are read and set by the executive."""

    def __init__(self, procedure: Procedure, mode: Mode, *, emit: Emit, notify: Callable[[], None],
                 hazardous: Callable[[Instruction], bool]) -> None:
        self.status = RunStatus.READY
        self.mode = mode
        self.frames: list[Frame] = [Frame(procedure, "", 0)]
        self.statuses = {i.number: InstructionStatus.PENDING for i in procedure.instructions}
        self.breakpoints: set[str] = set()
        self.paused = False
        self.at_breakpoint = False
        self.confirmed = False
        self.failure: str | None = None
        self.in_flight: str | None = None
        self.request: Request | None = None
        self.executing = False
        self.error: str | None = None
        self._announced: tuple[str, Hold] | None = None
        self._emit = emit
        self._notify = notify
        self._hazardous = hazardous

    def restore(self, replayed: Replayed) -> None:
        """Take the state a replay of the run's events found."""
        self.frames, self.mode, self.statuses = replayed.frames, replayed.mode, replayed.statuses
        self.breakpoints, self.failure, self.in_flight = replayed.breakpoints, replayed.failure, replayed.in_flight

    # ---- queries ----------------------------------------------------------------------------
    @property
    def frame(self) -> Frame:
        """The innermost frame: the procedure (or sub-procedure) the run is in."""
        return self.frames[-1]

    def current_number(self) -> str | None:
        return self.frame.number() if self.frame.instruction is not None else None

    def variables(self) -> dict[str, Any]:
        return {k: v for f in self.frames for k, v in f.env.items()}

    def unconfirmed(self, instruction: Instruction) -> bool:
        return self._hazardous(instruction) and not self.confirmed

    def hold(self) -> tuple[Hold | None, str]:
        """Why automation does not perform the current instruction now (None when it may)."""
        instruction = self.frame.instruction
        if self.status is not RunStatus.ACTIVE or instruction is None or self.executing or self.request:
            return None, ""
        number = self.current_number()
        if self.in_flight:
            return Hold.IN_FLIGHT, self.in_flight
        if self.failure:
            return Hold.FAILURE, f"{number} failed: {self.failure}"
        if isinstance(instruction, RecordInstruction):
            return Hold.OPERATOR_INPUT, f"{number}: {instruction.text}"
        if isinstance(instruction, ManualInstruction):
            return Hold.OPERATOR_ACTION, f"{number}: {instruction.text}"
        unconfirmed = self.unconfirmed(instruction)
        if self.mode is Mode.MANUAL:
            if unconfirmed:
                return Hold.CONFIRMATION, f"{number} is hazardous; confirm, then send: {instruction.describe()}"
            return Hold.MANUAL_MODE, f"{number}: {instruction.describe()}"
        if self.at_breakpoint:
            return Hold.BREAKPOINT, f"breakpoint at {number}"
        if self.paused:
            return Hold.PAUSED, f"automation paused at {number}"
        if not instruction.automatable:
            return Hold.NOT_AUTOMATABLE, f"{number} must be performed by an operator: {instruction.describe()}"
        if unconfirmed:
            return Hold.CONFIRMATION, f"{number} is hazardous; confirm to send: {instruction.describe()}"
        return None, ""

    def next_job(self) -> Job | None:
        """What PAX's thread should perform now: an operator's request, or the instruction automation may do."""
        if self.status is not RunStatus.ACTIVE or self.executing:
            return None
        frame = self.frame
        instruction = frame.instruction
        if instruction is None:
            return None
        if self.request is not None:
            return Job(frame, instruction, self.request.actor, self.request.then_pause)
        if self.hold()[0] is None:
            return Job(frame, instruction, PAX, False)
        return None

    def target(self, frame: Frame, instruction: Instruction, outcome: Outcome) -> int | None:
        """Where the run goes after the outcome; None means hold at a failure."""
        if outcome.ok:
            return _onward(frame, outcome)
        on_failure = _on_failure(instruction)
        return position_of(frame.procedure, on_failure) if on_failure else None

    # ---- moves ------------------------------------------------------------------------------
    def announce(self) -> None:
        """Record once per instruction and reason that automation waits for an operator."""
        self._notify()
        hold, reason = self.hold()
        if self.mode is not Mode.AUTONOMOUS or hold in (None, Hold.PAUSED, Hold.BREAKPOINT, Hold.MANUAL_MODE):
            return
        key = (self.current_number() or "", hold)
        if key != self._announced:
            self._announced = key
            self._emit(EventKind.AWAITING_OPERATOR, PAX, self.current_number(), hold=hold.value, reason=reason)

    def arrive(self) -> None:
        """Make the frame's position the current instruction."""
        self.confirmed = False
        self.failure = None
        number = self.current_number()
        if number is None:
            return
        self.statuses[number] = InstructionStatus.ACTIVE
        if self.mode is Mode.AUTONOMOUS and number in self.breakpoints:
            self.at_breakpoint = True
            self._emit(EventKind.BREAKPOINT_HIT, PAX, number)
        self.announce()

    def complete(self, actor: str, position: int, **data: Any) -> None:
        """The current instruction is done: record it and go to ``position``."""
        number = self.frame.number()
        self.statuses[number] = InstructionStatus.COMPLETED
        self._emit(EventKind.INSTRUCTION_COMPLETED, actor, number, next=self.frame.number(position), **data)
        self.advance(position)

    def skip(self, actor: str, reason: str) -> None:
        """Pass over the current instruction without performing it."""
        frame = self.frame
        number = frame.number()
        self.failure = self.in_flight = None
        self.statuses[number] = InstructionStatus.SKIPPED
        following = frame.procedure.following(frame.position)
        self._emit(EventKind.INSTRUCTION_SKIPPED, actor, number, reason=reason, next=frame.number(following))
        self.advance(following)

    def advance(self, position: int) -> None:
        """Move to ``position`` in the innermost frame; finish sub-procedures and the run at their end."""
        frame = self.frame
        frame.position = position
        while frame.instruction is None:
            if len(self.frames) == 1:
                self.status = RunStatus.COMPLETED
                self._emit(EventKind.RUN_COMPLETED, PAX, None)
                self._notify()
                return
            self.frames.pop()
            frame = self.frame
            number = frame.number()
            self.statuses[number] = InstructionStatus.COMPLETED
            frame.position = frame.procedure.following(frame.position)
            self._emit(EventKind.INSTRUCTION_COMPLETED, PAX, number, next=frame.number())
        self.arrive()

    def finish(self, job: Job, number: str, outcome: Outcome) -> None:
        """Follow the outcome of a job PAX's thread performed."""
        frame, instruction, actor = job.frame, job.instruction, job.actor
        if outcome.result is not None:
            name, values = outcome.result
            frame.env[name] = values
        if self.status is not RunStatus.ACTIVE:
            # stopped meanwhile: record how it ended so a resume knows, but go nowhere. A failure
            # (often the stop itself ending a wait) is redone on resume, never branched from; a
            # sub-procedure that was about to start simply starts again.
            if outcome.enter is not None:
                return
            self.statuses[number] = InstructionStatus.COMPLETED if outcome.ok else InstructionStatus.FAILED
            if outcome.ok:
                next_number = frame.number(self.target(frame, instruction, outcome))
                self._emit(EventKind.INSTRUCTION_COMPLETED, actor, number, next=next_number)
            else:
                self._emit(EventKind.INSTRUCTION_FAILED, actor, number, reason=outcome.reason, next=number)
            return
        if outcome.ok:
            if outcome.enter is not None:
                callee, inputs = outcome.enter
                self.frames.append(Frame(callee, f"{number}/", 0, dict(inputs)))
                self._emit(EventKind.CALL_ENTERED, actor, number, procedure=callee.id, inputs=dict(inputs))
                self.advance(0)
                return
            went = {"went_to": outcome.goto} if outcome.goto else {}
            self.complete(actor, _onward(frame, outcome), **went)
            return
        self.statuses[number] = InstructionStatus.FAILED
        target = self.target(frame, instruction, outcome)
        if target is not None:
            self._emit(EventKind.INSTRUCTION_FAILED, actor, number, reason=outcome.reason, next=frame.number(target),
                       branch=_on_failure(instruction))
            self.advance(target)
            return
        self.failure = outcome.reason
        self._emit(EventKind.INSTRUCTION_FAILED, actor, number, reason=outcome.reason, next=number)
        self.announce()

