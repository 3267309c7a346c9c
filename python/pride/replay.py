"""Rebuilding a run's state from its recorded events, so an interrupted run can be resumed.

The audit log is the run's only memory: :func:`replay` reads it back into where the run is
(its frames and their variables), what each instruction's status is, the mode and breakpoints,
and whether an instruction was in flight (a command sent with no result recorded). It decides
nothing; :meth:`pride.executive.Executive.resume` continues from what it returns.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from pride.events import Event, EventKind
from pride.frames import Frame, frames_at
from pride.model import Procedure
from pride.states import InstructionStatus, Mode

__all__ = ["Replayed", "replay", "result_values"]

_ENDED = {
    EventKind.INSTRUCTION_COMPLETED: InstructionStatus.COMPLETED,
    EventKind.INSTRUCTION_FAILED: InstructionStatus.FAILED,
    EventKind.INSTRUCTION_SKIPPED: InstructionStatus.SKIPPED,
}


@dataclass
class Replayed:
    """A run's state as its events left it."""

    frames: list[Frame]
    mode: Mode
    statuses: dict[str, InstructionStatus]
    breakpoints: set[str] = field(default_factory=set)
    failure: str | None = None  # the reason the current instruction failed, when it did
    in_flight: str | None = None  # why the current instruction holds: its command's outcome is unknown
    seq: int = 0


def result_values(data: dict[str, Any]) -> dict[str, Any]:
    """The variables a saved command result provides, from its COMMAND_RESULT event's data."""
    return {"success": data.get("success"), "message": data.get("message", ""), **(data.get("values") or {})}


def replay(procedure: Procedure, events: Sequence[Event], load: Callable[[str], Procedure], *,
           mode: Mode, statuses: dict[str, InstructionStatus]) -> Replayed:
    """The state of a run of ``procedure`` after ``events`` (``statuses``: the initial ones)."""
    state = Replayed(frames=[], mode=mode, statuses=dict(statuses))
    cursor = procedure.instructions[0].number
    envs: dict[str, dict[str, Any]] = {}
    started: str | None = None
    sent: str | None = None
    for event in events:
        number = event.instruction or ""
        prefix = number.rsplit("/", 1)[0] + "/" if "/" in number else ""
        kind = event.kind
        if kind in (EventKind.MODE_CHANGED, EventKind.RUN_RESUMED):
            state.mode = Mode(event.data["mode"])
        elif kind is EventKind.BREAKPOINT_SET:
            state.breakpoints.add(number)
        elif kind is EventKind.BREAKPOINT_CLEARED:
            state.breakpoints.discard(number)
        elif kind is EventKind.OPERATOR_INPUT:
            envs.setdefault(prefix, {})[event.data["name"]] = event.data["value"]
        elif kind is EventKind.COMMAND_SENT:
            sent = number
        elif kind is EventKind.COMMAND_RESULT:
            sent = None
            if event.data.get("result"):
                envs.setdefault(prefix, {})[event.data["result"]] = result_values(event.data)
        elif kind is EventKind.CALL_ENTERED:
            envs[number + "/"] = dict(event.data.get("inputs", {}))
        elif kind is EventKind.INSTRUCTION_STARTED:
            started = number
            state.statuses[number] = InstructionStatus.EXECUTING
        elif kind in _ENDED:
            state.statuses[number] = _ENDED[kind]
            cursor = event.data["next"]
            started = sent = None
            failed_here = kind is EventKind.INSTRUCTION_FAILED and cursor == number
            state.failure = event.data.get("reason") if failed_here else None
        state.seq = event.seq
    state.frames = frames_at(procedure, cursor, envs, load)
    if started is not None and started == cursor and sent is not None:
        state.in_flight = (f"{cursor} was in flight when the runner stopped: the command was sent and no "
                           "result was recorded. Check the system, then retry (resend) or skip it.")
    return state
