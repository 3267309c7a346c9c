"""Rebuilding a run's state from its recorded events, so an interrupted run can be resumed.

The audit log is the run's only memory: :func:`replay` reads it back into where the run is
(its frames and their variables), what each instruction's status is, the mode and breakpoints,
how many attempts each command had, whether the run was halted, and whether a command's outcome
is not known: sent with no result recorded (in flight when the runner died) or answered UNKNOWN.
Such a command's key is to be sent again as it is (``resend``): the habitat answers its outcome
or joins it, never runs it twice. It decides nothing; :meth:`pride.executive.Executive.resume`
continues from what it returns.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, assert_never

from pride import event_payloads as ep
from pride.events import Event, EventKind
from pride.frames import Frame, frames_at, position_of
from pride.leftovers import taken_back
from pride.run_section import RunSection
from pride.states import InstructionStatus, Mode, OperatorActionError
from procedure_language.model import Procedure

__all__ = ["Replayed", "replay", "result_values", "resumable_start"]

#: How an instruction's end leaves it.
_ENDED: dict[type, InstructionStatus] = {
    ep.InstructionCompleted: InstructionStatus.COMPLETED,
    ep.InstructionFailed: InstructionStatus.FAILED,
    ep.InstructionSkipped: InstructionStatus.SKIPPED,
    ep.InstructionHalted: InstructionStatus.HALTED,
}
#: Operator decisions after which a halt no longer holds the run.
_HALT_ENDS = (ep.Retry, ep.Continued, ep.SteppedBack, ep.WentTo, ep.InstructionSkipped, ep.OutcomeResolved)


@dataclass
class Replayed:
    """A run's state as its events left it."""

    frames: list[Frame]
    mode: Mode
    statuses: dict[str, InstructionStatus]
    breakpoints: set[str] = field(default_factory=set)
    failure: str | None = None  # the reason the current instruction failed, when it did
    in_flight: str | None = None  # a command sent without a key (an old log) and no result: why it holds
    resend: str | None = None  # the key of a command whose outcome is not known: send it again as it is
    unknown: tuple[str, str] | None = None  # (key, why) when the run was halted with an outcome unknown
    halt: tuple[str, str] | None = None  # (who, why) when the run was halted
    attempts: dict[str, int] = field(default_factory=dict)
    branches: dict[str, int] = field(default_factory=dict)  # times each instruction's on-failure branch was taken
    stops_after: int | None = None  # a run of part of the procedure: the last step it performs
    seq: int = 0


def result_values(data: ep.CommandResult) -> dict[str, Any]:
    """The variables a saved command result provides, from its COMMAND_RESULT event's data."""
    return {"success": data.success, "message": data.message, **data.values}


def resumable_start(procedure_id: str, events: Sequence[Event]) -> ep.RunStarted:
    """The start of the run ``events`` record, if a run of ``procedure_id`` may go on from them.

    Raises:
        OperatorActionError: the log holds no start, the run completed, it took back what it had
            added when it stopped (it cannot go on without it), or it ran another procedure.
    """
    started = events[0].data if events else None
    if not isinstance(started, ep.RunStarted):
        raise OperatorActionError("the log holds no start of that run")
    run_id = events[0].run_id
    if any(e.kind is EventKind.RUN_COMPLETED for e in events):
        raise OperatorActionError(f"run {run_id} is already completed")
    removed = taken_back(events)
    if removed:
        raise OperatorActionError(
            f"run {run_id} took back what it had added when it stopped ({', '.join(removed)}): "
            "it cannot go on without it; start the procedure again"
        )
    if started.procedure != procedure_id:
        raise OperatorActionError(f"run {run_id} ran procedure {started.procedure!r}, not {procedure_id!r}")
    return started


def _attempt(key: str) -> int:
    tail = key.rsplit("/", 1)[-1]
    return int(tail) if tail.isdigit() else 0


def replay(
    procedure: Procedure,
    events: Sequence[Event],
    load: Callable[[str], Procedure],
    *,
    mode: Mode,
    statuses: dict[str, InstructionStatus],
) -> Replayed:
    """The state of a run of ``procedure`` after ``events`` (``statuses``: the initial ones)."""
    state = Replayed(frames=[], mode=mode, statuses=dict(statuses))
    cursor = procedure.instructions[0].number
    envs: dict[str, dict[str, Any]] = {}
    started: str | None = None
    sent: str | None = None
    pending: str | None = None  # the key whose outcome is not known (in flight, unknown, asked again)
    unknown_why = ""
    for event in events:
        number = event.instruction or ""
        prefix = number.rsplit("/", 1)[0] + "/" if "/" in number else ""
        data = event.data
        match data:
            case ep.RunStarted() if data.section:
                section = RunSection.from_json(data.section)
                cursor = procedure.instructions[position_of(procedure, section.start)].number
                envs[""] = section.variables(procedure)
                state.stops_after = section.stops_after(procedure)
            case ep.ModeChanged() | ep.RunResumed():
                state.mode = Mode(data.mode)
            case ep.BreakpointSet():
                state.breakpoints.add(number)
            case ep.BreakpointCleared():
                state.breakpoints.discard(number)
            case ep.OperatorInput() | ep.RecordCorrected():
                envs.setdefault(prefix, {})[data.name] = data.value
            case ep.Halt():
                state.halt = (event.actor, data.reason)
            case ep.CommandSent():
                sent = number
                if data.key:
                    pending, unknown_why = data.key, ""
                    state.attempts[number] = max(state.attempts.get(number, 0), _attempt(data.key))
            case ep.CommandResult():
                sent = None
                if data.outcome == "unknown":
                    unknown_why = f"outcome of {data.key} unknown: {data.message}"
                    state.statuses[number] = InstructionStatus.OUTCOME_UNKNOWN
                else:
                    pending = None
                    if data.result:
                        envs.setdefault(prefix, {})[data.result] = result_values(data)
            case ep.OutcomeResolved():
                pending = None
            case ep.CallEntered():
                envs[number + "/"] = dict(data.inputs)
            case ep.MonitorViolated() | ep.MonitorCleared():
                pass  # what a monitor saw; the halt or hold it caused is recorded by itself
            case ep.ValueSet():
                envs.setdefault(prefix, {})[data.name] = data.value
            case ep.CallReturned():
                if data.result:
                    envs.setdefault(prefix, {})[data.result] = dict(data.outputs)
            case ep.InstructionStarted():
                started = number
                state.statuses[number] = InstructionStatus.EXECUTING
            case ep.SteppedBack():
                for again in data.reset:
                    state.statuses[again] = InstructionStatus.PENDING
                cursor, started, sent, pending, state.failure = data.next, None, None, None, None
            case ep.WentTo():
                cursor, started, sent, pending, state.failure = data.next, None, None, None, None
            case ep.InstructionCompleted() | ep.InstructionFailed() | ep.InstructionSkipped() | ep.InstructionHalted():
                state.statuses[number] = _ENDED[type(data)]
                cursor = data.next
                started = sent = pending = None
                failed_here = isinstance(data, ep.InstructionFailed) and cursor == number
                if isinstance(data, ep.InstructionFailed) and data.branch:
                    state.branches[number] = state.branches.get(number, 0) + 1
                state.failure = data.reason if failed_here and isinstance(data, ep.InstructionFailed) else None
                if isinstance(data, ep.InstructionHalted):
                    state.halt = (event.actor, data.reason)
            case (
                ep.RunStarted()
                | ep.RunCompleted()
                | ep.RunStopped()
                | ep.TelemetrySeen()
                | ep.Confirmation()
                | ep.ApprovalRequested()
                | ep.ApprovalGiven()
                | ep.ApprovalExpired()
                | ep.ActionRefused()
                | ep.SupervisorAttached()
                | ep.AwaitingOperator()
                | ep.Paused()
                | ep.Continued()
                | ep.BreakpointHit()
                | ep.Retry()
                | ep.LinkLost()
                | ep.LinkRestored()
                | ep.ControlTaken()
                | ep.ControlLost()
            ):
                pass  # they change nothing a resume needs (a halt's end is below)
            case _:
                assert_never(data)
        if isinstance(data, _HALT_ENDS):
            state.halt = None
        state.seq = event.seq
    state.frames = frames_at(procedure, cursor, envs, load)
    if pending is not None and started == cursor:
        state.resend = pending
        if state.halt is not None:  # halted: nothing is sent again until an operator decides
            state.unknown = (
                pending,
                unknown_why or f"outcome of {pending} unknown: in flight when the runner stopped, after a halt",
            )
    elif started is not None and started == cursor and sent is not None:
        state.in_flight = (
            f"{cursor} was in flight when the runner stopped: the command was sent without a key "
            "and no result was recorded. Check the system, then retry (resend) or skip it."
        )
    return state
