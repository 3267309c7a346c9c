"""A procedure as the page draws it: steps, numbered instructions as sentences, controls to show.

The page gets plain JSON so it never re-derives procedure meaning: each instruction's sentence
(:mod:`pride.phrasing`, with ``${...}`` as references the page fills in once the run knows them)
and its raw form, which instructions get a Send button (commands), a typed input (records, with
their constraints), a Done control (manual), the automatable mark, a hazard mark, the telemetry to
embed live with its SysRep label, units and limits, and the timeout a verify counts down;
and its monitors (``<monitor>``), each with the telemetry test the live run evaluates for it.
A call carries its sub-procedure (``callee``), whose instructions the executive numbers
``<call>/<number>`` (e.g. ``2.1/1.3``), so the page can draw and act on them in place.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from pride.phrasing import phrase, raw_form, template_json
from procedure_language.model import (
    BranchInstruction,
    CallInstruction,
    CommandInstruction,
    Condition,
    Instruction,
    Monitor,
    Notice,
    Procedure,
    RecordInstruction,
    Subject,
    VerifyInstruction,
    WaitInstruction,
)
from procedure_language.parser import load_procedure
from procedure_language.sysrep import SysRep

Loader = Callable[[str], Procedure]
#: Sub-procedures nest at most this deep in the view (lint rejects call cycles; this bounds the rest).
_MAX_DEPTH = 4

__all__ = ["TelemetryCheck", "check_key", "monitor_checks", "procedure_json", "telemetry_checks"]

#: (system, telemetry item, the condition an instruction tests it with, or None)
TelemetryCheck = tuple[str, str, Condition | None]


def procedure_json(
    procedure: Procedure, load: Loader = load_procedure, *, sysreps: Mapping[str, SysRep] | None = None, _depth: int = 0
) -> dict[str, Any]:
    """The page's view of a procedure, with the sub-procedures it calls."""
    sysreps = sysreps or {}
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
                "instructions": [_instruction(i, procedure, load, sysreps, _depth) for i in step.instructions],
            }
            for step in procedure.steps
        ],
        "monitors": [_monitor(m, procedure, sysreps) for step in procedure.steps for m in step.monitors],
    }


def check_key(system: str, item: str, condition: Condition | None) -> str:
    """How the page and the live run name one telemetry test (``cdra.filter_locked = false``)."""
    return f"{system}.{item} {condition.describe()}" if condition is not None else f"{system}.{item}"


def telemetry_checks(
    procedure: Procedure, load: Loader = load_procedure, *, _depth: int = 0
) -> dict[str, TelemetryCheck]:
    """Every telemetry test an instruction of the procedure or its sub-procedures makes, by check key."""
    checks: dict[str, TelemetryCheck] = {}
    for instruction in procedure.instructions:
        subject = _subject_of(instruction)
        if subject is not None and subject.source == "telemetry" and subject.system:
            condition = getattr(instruction, "condition", None)
            checks[check_key(subject.system, subject.name, condition)] = (subject.system, subject.name, condition)
        if isinstance(instruction, CallInstruction) and _depth < _MAX_DEPTH:
            checks.update(telemetry_checks(load(instruction.resolved_path), load, _depth=_depth + 1))
    return checks


#: What a monitor's violation does, in the panel's words (a go-to names its step).
_ON_VIOLATION = {"hold": "the run holds", "halt": "the run halts (the command in flight is cancelled)"}


def monitor_checks(procedure: Procedure) -> dict[str, TelemetryCheck]:
    """Every monitor's telemetry test by check key, for the live run to read and evaluate (a
    monitor of its item's limits reads the item, with no condition of its own)."""
    return {
        check_key(m.system, m.telemetry, m.condition): (m.system, m.telemetry, m.condition)
        for step in procedure.steps
        for m in step.monitors
    }


def _monitor(monitor: Monitor, procedure: Procedure, sysreps: Mapping[str, SysRep]) -> dict[str, Any]:
    """A monitor as the Monitors panel lists it; ``check``: its test's key (None: its item's limits)."""
    sysrep = sysreps.get(monitor.system)
    item = sysrep.telemetry_item(monitor.telemetry) if sysrep is not None else None
    goto = procedure.step(monitor.goto) if monitor.goto else None
    return {
        "name": monitor.name,
        "text": monitor.describe(),
        "system": monitor.system,
        "telemetry": monitor.telemetry,
        "label": item.label if item is not None else monitor.telemetry,
        "units": item.units if item is not None else None,
        "step": monitor.step,
        "scope": monitor.scope,
        "check": check_key(monitor.system, monitor.telemetry, monitor.condition) if monitor.condition else None,
        "limit": monitor.limit,
        "on_violation": f"the run halts and goes to {goto.number}. {goto.title}"
        if goto
        else _ON_VIOLATION.get(monitor.on_violation, monitor.on_violation),
    }


def _notice(notice: Notice) -> dict[str, str]:
    return {"level": notice.level, "text": notice.text}


def _subject_of(instruction: Instruction) -> Subject | None:
    if isinstance(instruction, (VerifyInstruction, WaitInstruction, BranchInstruction)):
        return instruction.subject
    return None


def _telemetry(subject: Subject, condition: Condition | None, sysreps: Mapping[str, SysRep]) -> dict[str, Any]:
    sysrep = sysreps.get(subject.system or "")
    item = sysrep.telemetry_item(subject.name) if sysrep is not None else None
    return {
        "system": subject.system,
        "item": subject.name,
        "check": check_key(subject.system or "", subject.name, condition),
        "label": item.label if item is not None else subject.name,
        "units": item.units if item is not None else None,
        "expected": condition.describe() if condition is not None else None,
        "limits": {"min": item.min, "max": item.max, "enum": list(item.enum) if item.enum else None}
        if item is not None
        else None,
    }


def _hazardous_in_sysrep(instruction: CommandInstruction, sysreps: Mapping[str, SysRep]) -> bool:
    sysrep = sysreps.get(instruction.system)
    command = sysrep.command(instruction.command) if sysrep is not None else None
    return bool(command is not None and command.hazardous)


def _instruction(
    instruction: Instruction, procedure: Procedure, load: Loader, sysreps: Mapping[str, SysRep], depth: int
) -> dict[str, Any]:
    callee = (
        load(instruction.resolved_path) if isinstance(instruction, CallInstruction) and depth < _MAX_DEPTH else None
    )
    sentence = phrase(instruction, sysreps, procedure, callee=callee)
    view: dict[str, Any] = {
        "number": instruction.number,
        "kind": instruction.kind.value,
        "text": str(sentence),
        "sentence": template_json(sentence),
        "raw": raw_form(instruction),
        "automatable": instruction.automatable,
        "needs_operator": instruction.needs_operator,
        "notices": [_notice(n) for n in instruction.notices],
    }
    subject = _subject_of(instruction)
    if subject is not None and subject.source == "telemetry":
        view["telemetry"] = _telemetry(subject, getattr(instruction, "condition", None), sysreps)
    if isinstance(instruction, (VerifyInstruction, WaitInstruction)):
        view["timeout"] = (
            instruction.seconds
            if isinstance(instruction, WaitInstruction) and instruction.seconds is not None
            else instruction.timeout
        )
    if isinstance(instruction, CommandInstruction):
        view.update(
            system=instruction.system,
            command=instruction.command,
            args=[{"name": a.name, "value": str(a.value)} for a in instruction.args],
            result=instruction.result,
            hazardous=instruction.hazardous or _hazardous_in_sysrep(instruction, sysreps),
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
        view["result"] = instruction.result
        if callee is not None:
            view["callee"] = procedure_json(callee, load, sysreps=sysreps, _depth=depth + 1)
    return view
