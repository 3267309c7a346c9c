"""Where a run is: a stack of frames, one per procedure being run (the main one and called ones).

Instruction numbers inside a called sub-procedure carry the caller's number as a prefix
(``3.2/1.1`` is instruction 1.1 of the sub-procedure called by 3.2), so one string names a
position anywhere in the stack; :func:`frames_at` rebuilds the stack from such a string.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from procedure_language.model import CallInstruction, Instruction, Procedure

__all__ = ["END", "Frame", "UnknownPositionError", "frames_at", "position_of"]

#: The number of the position after a procedure's last instruction.
END = "end"


@dataclass
class Frame:
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
        return self.prefix + (items[position].number if position < len(items) else END)


class UnknownPositionError(KeyError):
    """A recorded position names no instruction of the procedure (the log is of another version)."""

    def __init__(self, number: str) -> None:
        super().__init__(f"the log names instruction {number!r}, which the procedure does not have")
        self.number = number


def position_of(procedure: Procedure, step_ref: str) -> int:
    """The index of the first instruction of the step a go-to names."""
    step = procedure.step(step_ref)
    if step is None:  # lint rejects this; a procedure that skipped lint still must not run on
        raise KeyError(f"no step {step_ref!r}")
    first = step.instructions[0].number
    return next(n for n, i in enumerate(procedure.instructions) if i.number == first)


def frames_at(
    procedure: Procedure, cursor: str, envs: dict[str, dict[str, Any]], load: Callable[[str], Procedure]
) -> list[Frame]:
    """The stack of frames positioned at ``cursor``, each with the variables ``envs`` holds for its prefix."""
    frames: list[Frame] = []
    prefix = ""
    parts = cursor.split("/")
    for depth, part in enumerate(parts):
        items = procedure.instructions
        position = len(items) if part == END else next((n for n, i in enumerate(items) if i.number == part), None)
        if position is None:
            raise UnknownPositionError(prefix + part)
        frames.append(Frame(procedure, prefix, position, dict(envs.get(prefix, {}))))
        if depth + 1 < len(parts):
            call = items[position] if position < len(items) else None
            if not isinstance(call, CallInstruction):
                raise UnknownPositionError(prefix + part)
            procedure = load(call.resolved_path)
            prefix = f"{prefix}{part}/"
    return frames
