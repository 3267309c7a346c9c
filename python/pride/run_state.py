"""Where one run is and what holds it, and how it moves from instruction to instruction.

The executive (:mod:`pride.executive`) owns one :class:`RunState` and touches it only with its
lock held; it decides *who* may act and *when* (operators, PAX's thread). This module holds the
state and the moves: arriving at an instruction, completing it, following an outcome to the next
one (or holding: failed, halted, outcome unknown), entering and leaving sub-procedures, going
back within a step, and which hold applies now. Every move records its event through the
executive's ``emit`` (the journal first) as it makes it.

An on-failure branch is taken at most :data:`BRANCHES_BEFORE_HOLD` times from one instruction in
a run; after that the failure holds for an operator. A contingency step that loops back to itself
(plan again, move again) would otherwise retry a motion that cannot succeed for as long as the
run lasts, with nobody asked.

Command keys: each send of a command is an attempt with its own key
(:func:`pride.automation.command_key`); ``attempts`` counts them per instruction, so a retry, a
loop back or a step back sends a new key. Only two sends reuse a key: asking again about an
unknown outcome, and re-sending a command that was in flight when the runner died (``resend``).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Protocol

from pride.approvals import Approval, ApprovalPolicy, ApprovalRequest, CarriedApproval, self_approval_refusal
from pride.automation import Halt, InstructionResult, Send, command_key
from pride.event_payloads import (
    ActionRefused,
    ApprovalGiven,
    ApprovalRequested,
    AwaitingOperator,
    BreakpointHit,
    CallEntered,
    CallReturned,
    Confirmation,
    InstructionCompleted,
    InstructionFailed,
    InstructionHalted,
    InstructionSkipped,
    OutcomeResolved,
    RunCompleted,
    SteppedBack,
    WentTo,
)
from pride.events import PAX, Event, Payload
from pride.frames import Frame, position_of
from pride.leftovers import Holdings
from pride.monitoring import MonitorBoard
from pride.phrasing import filled_sentence
from pride.replay import Replayed
from pride.states import (
    CarriedApprovalSpent,
    Hold,
    InstructionStatus,
    Mode,
    OperatorActionError,
    RefusalRule,
    RunStatus,
)
from procedure_language.model import (
    CallInstruction,
    CommandInstruction,
    Instruction,
    ManualInstruction,
    Procedure,
    RecordInstruction,
    VerifyInstruction,
    WaitInstruction,
)
from procedure_language.sysrep import SysRep

__all__ = ["Emit", "Job", "Request", "RunState"]


class Emit(Protocol):
    """The executive's ``_emit``: records an event durably, then tells observers."""

    def __call__(self, actor: str, instruction: str | None, data: Payload, /) -> Event: ...


@dataclass(frozen=True)
class Request:
    """An operator asked PAX's thread to perform the current instruction on their behalf."""

    actor: str
    then_pause: bool = False


@dataclass(frozen=True)
class Job:
    """An instruction PAX's thread is to perform now, and for whom (a command: with its key)."""

    frame: Frame
    instruction: Instruction
    actor: str
    then_pause: bool
    send: Send | None = None


#: Times one instruction's on-failure branch is taken in a run before its failure holds instead.
BRANCHES_BEFORE_HOLD = 3


def _on_failure(instruction: Instruction) -> str | None:
    if isinstance(instruction, (CommandInstruction, VerifyInstruction, WaitInstruction)):
        return instruction.on_failure
    return None


def _onward(frame: Frame, outcome: InstructionResult) -> int:
    """Where a successful outcome leads: the step it went to, or the instruction that follows."""
    return position_of(frame.procedure, outcome.goto) if outcome.goto else frame.procedure.following(frame.position)


class RunState:
    """The state of one run; see the module docstring. Fields are read and set by the executive."""

    def __init__(
        self,
        procedure: Procedure,
        mode: Mode,
        *,
        run_id: str,
        emit: Emit,
        notify: Callable[[], None],
        hazardous: Callable[[Instruction], bool],
        sysreps: Mapping[str, SysRep],
        holdings: Holdings,
        approvals: ApprovalPolicy,
    ) -> None:
        """``holdings``: what the run added to its systems (its completion lists what is left);
        ``approvals``: which commands need a second operator's approval (:mod:`pride.approvals`)."""
        self.run_id = run_id
        self.status = RunStatus.READY
        self.stopping = False  # a stop is under way: the run moves on no more, nobody answers its holds
        self.mode = mode
        self.frames: list[Frame] = [Frame(procedure, "", 0)]
        self.statuses = {i.number: InstructionStatus.PENDING for i in procedure.instructions}
        self.breakpoints: set[str] = set()
        self.paused = False
        self.at_breakpoint = False
        self.confirmed_by: str | None = None  # who confirmed the current hazardous command
        self.approvals = approvals
        self.approval_request: ApprovalRequest | None = None  # the current command, sent for approval
        self.approval: Approval | None = None  # ... and approved by a second operator
        self.failure: str | None = None
        self.in_flight: str | None = None  # a log from before command keys: sent, no result, no key
        self.unknown: tuple[str, str] | None = None  # (key, why) of the command whose outcome is unknown
        self.resend: str | None = None  # a key to send again as it is (in flight when the runner died)
        self.halt: Halt | None = None
        #: How many times an operator decided what to do about a hold: a halt whose robot answers after
        #: an operator already carried on must not hold the run again.
        self.carried_on = 0
        self.stops_after: int | None = None  # a run of part of the procedure ends after this step
        self.monitors = MonitorBoard(procedure, sysreps)
        self.diverted: tuple[str, str] | None = None  # a monitor's go-to (step, why), once what runs has ended
        self.control_lost: str | None = None  # why this run may not command its robot
        self.attempts: dict[str, int] = {}  # instruction number -> attempts at its command so far
        self.branches: dict[str, int] = {}  # instruction number -> times its on-failure branch was taken
        self.request: Request | None = None
        self.executing = False
        self.error: str | None = None
        self._announced: tuple[str, Hold] | None = None
        self._emit = emit
        self._notify = notify
        self._hazardous = hazardous
        self._sysreps = sysreps  # their labels word the sentence a hold shows
        self._holdings = holdings

    def restore(self, replayed: Replayed) -> None:
        """Take the state a replay of the run's events found."""
        self.frames, self.mode, self.statuses = replayed.frames, replayed.mode, replayed.statuses
        self.breakpoints, self.failure, self.in_flight = replayed.breakpoints, replayed.failure, replayed.in_flight
        self.unknown, self.resend, self.attempts = replayed.unknown, replayed.resend, replayed.attempts
        self.branches = replayed.branches
        self.halt = Halt(*replayed.halt) if replayed.halt else None
        self.stops_after = replayed.stops_after
        in_steps = {int(n.split(".")[0]) for n, s in self.statuses.items() if s is not InstructionStatus.PENDING}
        current = self.frames[0].number() if self.frames and self.frames[0].instruction is not None else None
        self.monitors.resume(in_steps, int(current.split(".")[0]) if current else None)

    # ---- queries ----------------------------------------------------------------------------
    @property
    def going_on(self) -> bool:
        """Whether the run may still move on: active, and no stop under way."""
        return self.status is RunStatus.ACTIVE and not self.stopping

    @property
    def frame(self) -> Frame:
        """The innermost frame: the procedure (or sub-procedure) the run is in."""
        return self.frames[-1]

    def current_number(self) -> str | None:
        return self.frame.number() if self.frame.instruction is not None else None

    def variables(self) -> dict[str, Any]:
        return {k: v for f in self.frames for k, v in f.env.items()}

    def needs_approval(self, instruction: Instruction) -> bool:
        """Whether a second operator must approve this instruction's command before it is sent."""
        return self.approvals.needs_approval(isinstance(instruction, CommandInstruction), self._hazardous(instruction))

    def unconfirmed(self, instruction: Instruction) -> bool:
        """Whether the instruction may not be sent yet: not approved (critical commanding), or a
        hazardous command not confirmed."""
        if self.needs_approval(instruction):
            return self.approval is None
        return self._hazardous(instruction) and self.confirmed_by is None

    def unconfirmed_text(self, number: str | None, instruction: Instruction) -> str:
        """What an operator must do first about an unconfirmed command."""
        if not self.needs_approval(instruction):
            return f"{number} is a hazardous command: confirm it first"
        if self.approval_request is not None:
            sender = self.approval_request.sender
            return f"{number} waits for a second operator's approval (sent for approval by {sender})"
        return f"{number} needs a second operator's approval: send it for approval first"

    def clear_to_send(self) -> bool:
        """Whether nothing but its approval holds the current command back: after a failure, a halt or
        an unknown outcome an operator still decides (retry, ask again, ...) once it is approved."""
        return not (self.failure or self.in_flight or self.unknown or self.resend or self.halt or self.control_lost)

    def approval_json(self) -> dict[str, Any] | None:
        """The current command's approval as views show it: needed (nobody sent it for approval
        yet), requested or approved (None: it needs none)."""
        approval, request = self.approval, self.approval_request
        if approval is not None:
            request = approval.request
        if request is None:
            instruction = self.frame.instruction
            if instruction is None or not self.going_on or not self.needs_approval(instruction):
                return None
            return {"number": self.current_number(), "state": "needed", "level": self.approvals.level.value}
        shown: dict[str, Any] = {
            "number": request.number,
            "sender": request.sender,
            "asked": request.asked.isoformat(),
            "command": request.command,
            "state": "requested",
        }
        if approval is not None:
            shown.update(state="approved", approver=approval.approver, expires=approval.expires.isoformat())
        return shown

    def _unconfirmed_hold(self, instruction: Instruction, number: str | None, text: str, then: str) -> tuple[Hold, str]:
        if not self.needs_approval(instruction):
            return Hold.CONFIRMATION, f"{number} is hazardous; {then}: {text}"
        if self.approval_request is not None:
            sender = self.approval_request.sender
            return Hold.APPROVAL, f"{number} waits for a second operator's approval (sent by {sender}): {text}"
        return Hold.CONFIRMATION, f"{number} needs a second operator's approval; send it for approval: {text}"

    def halt_text(self) -> str:
        """ "halted by USER: reason" (empty without a halt)."""
        if self.halt is None:
            return ""
        return f"halted by {self.halt.user}" + (f": {self.halt.reason}" if self.halt.reason else "")

    def hold(self) -> tuple[Hold | None, str]:
        """Why automation does not perform the current instruction now (None when it may)."""
        instruction = self.frame.instruction
        if not self.going_on or instruction is None or self.executing or self.request:
            return None, ""
        number = self.current_number()
        if self.control_lost:
            return Hold.CONTROL_LOST, self.control_lost
        if self.unknown:
            return Hold.OUTCOME_UNKNOWN, f"{number}: {self.unknown[1]}"
        if self.in_flight:
            return Hold.IN_FLIGHT, self.in_flight
        if self.halt and self.diverted is not None:
            return None, ""  # a monitor's go-to takes the run on once its halt is recorded: nobody answers it
        if self.halt:
            halted_here = self.statuses.get(self.frame.number()) is InstructionStatus.HALTED
            where = f"{number} was halted before it finished" if halted_here else f"at {number}"
            return Hold.HALTED, f"{self.halt_text()} ({where})"
        if self.failure:
            return Hold.FAILURE, f"{number} failed: {self.failure}"
        if self.resend:
            return None, ""  # PAX sends the same key again by itself: the habitat answers its outcome
        text = filled_sentence(instruction, self._sysreps, self.frame.procedure, self.frame.env)
        if isinstance(instruction, RecordInstruction):
            return Hold.OPERATOR_INPUT, f"{number}: {text}"
        if isinstance(instruction, ManualInstruction):
            return Hold.OPERATOR_ACTION, f"{number}: {text}"
        unconfirmed = self.unconfirmed(instruction)
        if self.mode is Mode.MANUAL:
            if unconfirmed:
                return self._unconfirmed_hold(instruction, number, text, "confirm, then send")
            return Hold.MANUAL_MODE, f"{number}: {text}"
        if self.at_breakpoint:
            return Hold.BREAKPOINT, f"breakpoint at {number}"
        if self.paused:
            return Hold.PAUSED, f"automation paused at {number}"
        if not instruction.automatable:
            return Hold.NOT_AUTOMATABLE, f"{number} must be performed by an operator: {text}"
        if unconfirmed:
            return self._unconfirmed_hold(instruction, number, text, "confirm to send")
        return None, ""

    def next_job(self) -> Job | None:
        """What PAX's thread should perform now: an operator's request, or the instruction automation may do."""
        if not self.going_on or self.executing:
            return None
        frame = self.frame
        instruction = frame.instruction
        if instruction is None:
            return None
        if self.request is not None:
            actor, then_pause = self.request.actor, self.request.then_pause
        elif self.hold()[0] is None:
            actor, then_pause = PAX, False
        else:
            return None
        send = None
        if isinstance(instruction, CommandInstruction):
            number = frame.number()
            if self._approval_expired(number):
                return None
            key = self.resend or command_key(self.run_id, number, self.attempts.get(number, 0) + 1)
            approval = self.approval
            send = Send(
                key,
                resend=self.resend is not None,
                confirmed_by=self.confirmed_by,
                requested_by=approval.request.sender if approval else None,
                approved_by=approval.approver if approval else None,
            )
        return Job(frame, instruction, actor, then_pause, send)

    def _approval_expired(self, number: str) -> bool:
        """Drop an approval that ran out before its command could be sent (recorded; the command
        waits for a new one): a command is never sent on a stale approval."""
        approval = self.approval
        now = self.approvals.clock()
        if approval is None or self.resend or not approval.stale(now):
            return False
        self.approval = self.approval_request = None
        self.request = None
        self._emit(PAX, number, approval.expiry_record())
        self.announce()
        return True

    def confirm(self, user: str, instruction: Instruction, said: str) -> None:
        """``user`` confirmed the current hazardous command (``said``: its sentence, filled); under
        critical commanding, they sent it for a second operator's approval, as its sender."""
        number = self.current_number()
        if self.needs_approval(instruction):
            if self.approval_request is not None or self.approval is not None:
                raise OperatorActionError(self.unconfirmed_text(number, instruction))
            self.approval_request = ApprovalRequest(number or "", user, self.approvals.clock(), said)
            self._emit(user, number, ApprovalRequested(command=said, level=self.approvals.level.value))
        elif not self._hazardous(instruction):
            raise OperatorActionError(f"{number} is not a hazardous command")
        else:
            self.confirmed_by = user
            self._emit(user, number, Confirmation(command=said))
        self.announce()

    def approve(self, user: str, carried: CarriedApproval | None) -> None:
        """``user`` approved the command sent for approval, as the second operator (``carried``: given
        on the ground before an onboard unit went up); see :meth:`pride.executive.Executive.approve`."""
        number = self.current_number()
        request = self.approval_request
        if request is None or request.number != number:
            raise OperatorActionError(f"{number} waits for no approval")
        refusal = self_approval_refusal(request, user)
        if refusal is not None:  # on the record whoever asked: a console, a terminal, the habitat
            rule = RefusalRule.TWO_PERSON
            self._emit(user, number, ActionRefused(action="approve", rule=rule.value, reason=refusal))
            raise OperatorActionError(refusal, rule=rule, recorded=True)
        try:
            approval = carried.approval(request) if carried else Approval.given(request, user, self.approvals)
        except ValueError as exc:
            raise (CarriedApprovalSpent if carried else OperatorActionError)(str(exc)) from None
        if approval.stale(self.approvals.clock()):
            self._emit(user, number, approval.expiry_record())
            raise CarriedApprovalSpent(
                f"{user}'s approval of {number}, carried with the unit, ran out at "
                f"{approval.expires.isoformat()[11:19]} UTC: a second operator approves it again from the ground"
            )
        self.approval = approval
        given = ApprovalGiven(
            sender=request.sender,
            command=request.command,
            expires=approval.expires.isoformat(),
            given=approval.approved.isoformat() if carried else None,
            carried=carried is not None,
        )
        self._emit(user, number, given)
        if self.mode is Mode.MANUAL and self.clear_to_send():  # the sender pressed Send: it goes now, as theirs
            self.request = Request(request.sender)
        self.announce()  # wakes PAX's thread too

    def begin(self, job: Job) -> str:
        """PAX's thread takes ``job``: the instruction is executing (a command's attempt is counted)."""
        number = job.frame.number()
        self.executing = True
        self.request = None
        self.resend = None
        self.statuses[number] = InstructionStatus.EXECUTING
        if job.send is not None and not job.send.resend:
            self.attempts[number] = self.attempts.get(number, 0) + 1
        return number

    def target(self, frame: Frame, instruction: Instruction, outcome: InstructionResult) -> int | None:
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
        if hold in (None, Hold.PAUSED, Hold.BREAKPOINT, Hold.MANUAL_MODE):
            return
        if self.mode is not Mode.AUTONOMOUS and hold not in (Hold.OUTCOME_UNKNOWN, Hold.HALTED, Hold.CONTROL_LOST):
            return
        key = (self.current_number() or "", hold)
        if key != self._announced:
            self._announced = key
            self._emit(PAX, self.current_number(), AwaitingOperator(hold=hold.value, reason=reason))

    def arrive(self) -> None:
        """Make the frame's position the current instruction."""
        self.confirmed_by = None
        self.approval = self.approval_request = None
        self.failure = None
        number = self.current_number()
        if number is None:
            return
        self.monitors.enter(int(self.frames[0].number().split(".")[0]))
        self.statuses[number] = InstructionStatus.ACTIVE
        if self.mode is Mode.AUTONOMOUS and number in self.breakpoints:
            self.at_breakpoint = True
            self._emit(PAX, number, BreakpointHit())
        self.announce()

    def complete(self, actor: str, position: int, *, went_to: str | None = None) -> None:
        """The current instruction is done (``went_to``: the step a branch or go-to chose): record it
        and go to ``position``."""
        number = self.frame.number()
        self.statuses[number] = InstructionStatus.COMPLETED
        self._emit(actor, number, InstructionCompleted(next=self.frame.number(position), went_to=went_to))
        self.advance(position, actor)

    def enter_section(self, step: str, variables: dict[str, Any], stops_after: int | None) -> None:
        """Start at ``step`` with ``variables`` bound, and end after step ``stops_after`` (None: at the end)."""
        frame = self.frames[0]
        frame.position, self.stops_after = position_of(frame.procedure, step), stops_after
        frame.env.update(variables)

    def _beyond_section(self, frame: Frame) -> bool:
        """Whether the main procedure moved past the last step of the run's section (a contingency
        step anywhere is still the section's: an off-nominal path of a step in it)."""
        instruction = frame.instruction
        if self.stops_after is None or len(self.frames) > 1 or instruction is None:
            return False
        step = frame.procedure.step_of(instruction.number)
        return step.number > self.stops_after and not step.contingency

    def go_to(self, step: str, actor: str, reason: str) -> None:
        """Go to ``step`` of the main procedure (leaving any sub-procedure) by no instruction's doing."""
        was = self.frame.number()
        del self.frames[1:]
        main = self.frames[0]
        main.position = position_of(main.procedure, step)
        self.clear_holds()
        self._emit(actor, was, WentTo(from_=was, next=main.number(), reason=reason))
        self.arrive()

    def clear_holds(self) -> None:
        """An operator decided what to do about the current instruction: no failure, halt or unknown stays."""
        self.failure = self.in_flight = self.unknown = self.resend = None
        self.halt = None
        self.carried_on += 1

    def skip(self, actor: str, reason: str) -> None:
        """Pass over the current instruction without performing it."""
        frame = self.frame
        number = frame.number()
        self.clear_holds()
        self.statuses[number] = InstructionStatus.SKIPPED
        following = frame.procedure.following(frame.position)
        self._emit(actor, number, InstructionSkipped(reason=reason, next=frame.number(following)))
        self.advance(following, actor)

    def go_back(self, actor: str, position: int, reason: str) -> None:
        """Return to an earlier instruction of the frame: it and those after it are performed again."""
        frame = self.frame
        number = frame.number()
        reset = [frame.number(p) for p in range(position, frame.position + 1)]
        self.clear_holds()
        for again in reset:
            self.statuses[again] = InstructionStatus.PENDING
        self._emit(
            actor, number, SteppedBack(from_=number, next=frame.number(position), reset=tuple(reset), reason=reason)
        )
        frame.position = position
        self.arrive()

    def advance(self, position: int, actor: str = PAX) -> None:
        """Move to ``position`` in the innermost frame; finish sub-procedures and the run at their end.

        ``actor`` is whoever's action got the run here: the end of the run is credited to them.
        """
        frame = self.frame
        frame.position = position
        while frame.instruction is None or self._beyond_section(frame):
            if len(self.frames) == 1:
                self.status = RunStatus.COMPLETED
                left = self._holdings.left("the procedure completed without removing it")
                self._emit(actor, None, RunCompleted(taken_back=left.removed, left_behind=left.left_json()))
                self._notify()
                return
            done = self.frames.pop()
            frame = self.frame
            number = frame.number()
            self._hand_back(done, frame, number, actor)
            self.statuses[number] = InstructionStatus.COMPLETED
            frame.position = frame.procedure.following(frame.position)
            self._emit(actor, number, InstructionCompleted(next=frame.number()))
        self.arrive()

    def _hand_back(self, done: Frame, caller: Frame, number: str, actor: str) -> None:
        """A sub-procedure that declares outputs ended: its caller reads them under the call's ``result``."""
        if not done.procedure.outputs:
            return
        outputs = {o.name: done.env[o.name] for o in done.procedure.outputs if o.name in done.env}
        call = caller.instruction
        result = call.result if isinstance(call, CallInstruction) else None
        if result:
            caller.env[result] = outputs
        self._emit(actor, number, CallReturned(procedure=done.procedure.id, result=result, outputs=outputs))

    def halted(self, number: str, actor: str, detail: str) -> None:
        """A halt ended the instruction: recorded as halted by whoever halted, never completed."""
        halt = self.halt or Halt(actor, "")
        self.statuses[number] = InstructionStatus.HALTED
        self._emit(halt.user, number, InstructionHalted(reason=halt.reason, detail=detail, next=number))

    def resolve(self, actor: str, key: str, succeeded: bool, reason: str) -> None:
        """An operator recorded what became of command ``key`` (outcome unknown); follow it."""
        frame = self.frame
        instruction = frame.instruction
        assert instruction is not None
        number = frame.number()
        self.clear_holds()
        self._emit(
            actor, number, OutcomeResolved(key=key, outcome="succeeded" if succeeded else "failed", reason=reason)
        )
        finding = f"recorded by {actor}: {reason}"
        if isinstance(instruction, CommandInstruction) and instruction.result:
            frame.env[instruction.result] = {"success": succeeded, "message": finding}
        if succeeded:
            self.complete(actor, frame.procedure.following(frame.position))
        else:
            self._fail(frame, instruction, number, actor, InstructionResult(False, f"{key} failed ({finding})"))

    def finish(self, job: Job, number: str, outcome: InstructionResult) -> None:
        """Follow the outcome of a job PAX's thread performed."""
        frame, instruction, actor = job.frame, job.instruction, job.actor
        if outcome.result is not None:
            name, values = outcome.result
            frame.env[name] = values
        if not outcome.ok:
            self.confirmed_by = None  # a hazardous command is confirmed again before a new attempt
            self.approval = self.approval_request = None  # ... and approved again
        if outcome.unknown_key is not None:
            # neither done nor failed: it waits here (a resume asks again) until an operator decides
            self.statuses[number] = InstructionStatus.OUTCOME_UNKNOWN
            self.unknown = (outcome.unknown_key, outcome.reason)
            self.announce()
            return
        if outcome.halted:
            self.halted(number, actor, outcome.reason)
            if self.diverted is None:  # a monitor's go-to takes the run on from here
                self.announce()
            return
        if not self.going_on:
            # stopped meanwhile: record how it ended so a resume knows, but go nowhere. A failure is
            # redone on resume, never branched from; a sub-procedure about to start starts again.
            if outcome.enter is not None:
                return
            self.statuses[number] = InstructionStatus.COMPLETED if outcome.ok else InstructionStatus.FAILED
            if outcome.ok:
                next_number = frame.number(self.target(frame, instruction, outcome))
                self._emit(actor, number, InstructionCompleted(next=next_number))
            else:
                self._emit(actor, number, InstructionFailed(reason=outcome.reason, next=number))
            return
        if outcome.ok:
            if outcome.enter is not None:
                callee, inputs = outcome.enter
                self.frames.append(Frame(callee, f"{number}/", 0, dict(inputs)))
                self._emit(actor, number, CallEntered(procedure=callee.id, inputs=dict(inputs)))
                self.advance(0, actor)
                return
            self.complete(actor, _onward(frame, outcome), went_to=outcome.goto or None)
            return
        self._fail(frame, instruction, number, actor, outcome)

    def _fail(
        self, frame: Frame, instruction: Instruction, number: str, actor: str, outcome: InstructionResult
    ) -> None:
        """The instruction failed: to its on-failure step if it has one, else hold for an operator."""
        self.statuses[number] = InstructionStatus.FAILED
        target = self.target(frame, instruction, outcome)
        reason = outcome.reason
        if target is not None and self.branches.get(number, 0) >= BRANCHES_BEFORE_HOLD:
            reason = (
                f"{reason} (its on-failure step {_on_failure(instruction)!r} was already taken "
                f"{self.branches[number]} times in this run: an operator decides)"
            )
            target = None
        if target is not None:
            self.branches[number] = self.branches.get(number, 0) + 1
            failed = InstructionFailed(
                reason=outcome.reason, next=frame.number(target), branch=_on_failure(instruction)
            )
            self._emit(actor, number, failed)
            self.advance(target, actor)
            return
        self.failure = reason
        self._emit(actor, number, InstructionFailed(reason=reason, next=number))
        self.announce()
