"""A procedure as the page draws it: steps, numbered instructions, notices, controls to show.

The page gets plain JSON so it never re-derives procedure meaning: which instructions get a
Send button (commands), a typed input (records, with their constraints), a Done control
(manual), the automatable icon, a hazard mark, and which telemetry items to embed live.
A call carries its sub-procedure (``callee``), whose instructions the executive numbers
``<call>/<number>`` (e.g. ``2.1/1.3``), so the page can draw and act on them in place.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from pride.model import (
    BranchInstruction, CallInstruction, CommandInstruction, Instruction, Notice, Procedure,
    RecordInstruction, Subject, VerifyInstruction, WaitInstruction,
)
from pride.parser import load_procedure

Loader = Callable[[str], Procedure]
#: Sub-procedures nest at most this deep in the view (lint rejects call cycles; this bounds the rest).
_MAX_DEPTH = 4

__all__ = ["procedure_json", "telemetry_references"]


def procedure_json(procedure: Procedure, load: Loader = load_procedure, *, _depth: int = 0) -> dict[str, Any]:
    """The page's view of a procedure, with the sub-procedures it calls."""
    return {
        "id": procedure.id,
        "title": procedure.title,
        "version": procedure.version,
        "description": procedure.description,
        "uses": [system for system, _ in procedure.uses],
        "steps": [
            {
                "number": step.number,
                "id": step.id,
                "title": step.title,
                "notices": [_notice(n) for n in step.notices],
                "instructions": [_instruction(i, load, _depth) for i in step.instructions],
            }
            for step in procedure.steps
        ],
    }


def telemetry_references(procedure: Procedure, load: Loader = load_procedure, *, _depth: int = 0) -> set[tuple[str, str]]:
    """Every (system, telemetry item) an instruction of the procedure or its sub-procedures reads."""
    refs = set()
    for instruction in procedure.instructions:
        subject = _subject_of(instruction)
        if subject is not None and subject.source == "telemetry" and subject.system:
            refs.add((subject.system, subject.name))
        if isinstance(instruction, CallInstruction) and _depth < _MAX_DEPTH:
            refs |= telemetry_references(load(instruction.resolved_path), load, _depth=_depth + 1)
    return refs


def _notice(notice: Notice) -> dict[str, str]:
    return {"level": notice.level, "text": notice.text}


def _subject_of(instruction: Instruction) -> Subject | None:
    if isinstance(instruction, (VerifyInstruction, WaitInstruction, BranchInstruction)):
        return instruction.subject
    return None


def _instruction(instruction: Instruction, load: Loader, depth: int) -> dict[str, Any]:
    view: dict[str, Any] = {
        "number": instruction.number,
        "kind": instruction.kind.value,
        "text": instruction.describe(),
        "automatable": instruction.automatable,
        "needs_operator": instruction.needs_operator,
        "notices": [_notice(n) for n in instruction.notices],
    }
    subject = _subject_of(instruction)
    if subject is not None and subject.source == "telemetry":
        view["telemetry"] = {"system": subject.system, "item": subject.name}
    if isinstance(instruction, CommandInstruction):
        view.update(
            system=instruction.system,
            command=instruction.command,
            args=[{"name": a.name, "value": str(a.value)} for a in instruction.args],
            result=instruction.result,
            hazardous=instruction.hazardous,
        )
    elif isinstance(instruction, RecordInstruction):
        view["record"] = {
            "name": instruction.name,
            "type": instruction.type,
            "min": instruction.minimum,
            "max": instruction.maximum,
            "pattern": instruction.pattern,
            "choices": list(instruction.choices) if instruction.choices else None,
        }
    elif isinstance(instruction, CallInstruction):
        view["procedure"] = instruction.procedure
        if depth < _MAX_DEPTH:
            view["callee"] = procedure_json(load(instruction.resolved_path), load, _depth=depth + 1)
    return view
