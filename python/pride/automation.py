"""How PAX carries out an instruction on the systems: send commands, watch and read telemetry.

The executive (:mod:`pride.executive`) decides *what* runs and *when*; this module does the
blocking part, on PAX's thread and without the executive's lock: a command waits for the
system's answer, a verify or wait watches telemetry until its condition holds or its timeout
passes. Everything it sends and every telemetry value it decides on is recorded through the
``record`` callback before it acts on it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from pride.events import EventKind
from pride.model import (
    BranchInstruction, CallInstruction, CommandInstruction, GoToInstruction, Instruction, Procedure,
    RecordInstruction, Reference, Subject, VerifyInstruction, WaitInstruction, lookup,
)
from pride.states import OperatorActionError
from pride.sysrep import SysRep, check_value
from pride.systems import SystemGateway

__all__ = ["Automation", "Outcome"]

_TELEMETRY_POLL_S = 0.25


@dataclass
class Outcome:
    """How an instruction ended: ok or not (with the reason), and where the run goes next."""

    ok: bool
    reason: str = ""
    goto: str | None = None  # a step reference to continue at
    result: tuple[str, dict[str, Any]] | None = None  # a saved command result: (name, values)
    enter: tuple[Procedure, dict[str, Any]] | None = None  # a sub-procedure to run, with its inputs


class Automation:
    """Carries out automatable instructions against a gateway for one run."""

    def __init__(
        self,
        gateway: SystemGateway,
        sysreps: Mapping[str, SysRep],
        load: Callable[[str], Procedure],
        record: Callable[..., Any],
    ) -> None:
        """``record(kind, actor, number, **data)`` stores an event (the executive's, taking its lock)."""
        self._gateway = gateway
        self._sysreps = dict(sysreps)
        self._load = load
        self._record = record
        self.abort = threading.Event()  # set when the run stops: waits and watches end early
        self.telemetry_changed = threading.Event()  # set by the gateway's listener

    def is_hazardous(self, instruction: Instruction) -> bool:
        """Whether an instruction is a command that needs confirmation (marked so, or so in its SysRep)."""
        if not isinstance(instruction, CommandInstruction):
            return False
        sysrep = self._sysreps.get(instruction.system)
        command = sysrep.command(instruction.command) if sysrep is not None else None
        return instruction.hazardous or bool(command is not None and command.hazardous)

    def carry_out(self, env: dict[str, Any], procedure: Procedure, instruction: Instruction, number: str, actor: str) -> Outcome:
        """Perform one instruction as ``actor``; only returns once it has finished or failed."""
        if isinstance(instruction, CommandInstruction):
            return self._send(env, instruction, number, actor)
        if isinstance(instruction, VerifyInstruction):
            return self._watch(instruction.subject, instruction.condition, instruction.timeout, number, actor)
        if isinstance(instruction, WaitInstruction):
            if instruction.seconds is not None:
                if self.abort.wait(instruction.seconds):
                    return Outcome(False, "the run was stopped during the wait")
                return Outcome(True)
            return self._watch(instruction.subject, instruction.condition, instruction.timeout, number, actor)
        if isinstance(instruction, BranchInstruction):
            value = self._read(env, instruction.subject, number, actor)
            holds = instruction.condition.holds(value, self._type_of(procedure, instruction.subject))
            return Outcome(True, goto=instruction.goto if holds else instruction.else_goto)
        if isinstance(instruction, GoToInstruction):
            return Outcome(True, goto=instruction.step)
        if isinstance(instruction, CallInstruction):
            callee = self._load(instruction.resolved_path)
            declared = {i.name: i.type for i in callee.inputs}
            inputs = {a.name: check_value(a.name, declared.get(a.name, "string"), a.value.resolve(env))
                      for a in instruction.args}
            return Outcome(True, enter=(callee, inputs))
        raise OperatorActionError(f"{number} is performed by an operator")

    def _send(self, env: dict[str, Any], instruction: CommandInstruction, number: str, actor: str) -> Outcome:
        sysrep = self._sysreps.get(instruction.system)
        command = sysrep.command(instruction.command) if sysrep is not None else None
        args: dict[str, Any] = {}
        for binding in instruction.args:
            value = binding.value.resolve(env)
            argument = command.arg(binding.name) if command is not None else None
            try:
                args[binding.name] = argument.check(value) if argument is not None else value
            except ValueError as exc:
                return Outcome(False, f"argument {exc}")
        self._record(EventKind.COMMAND_SENT, actor, number, system=instruction.system, command=instruction.command,
                     args=args, hazardous=self.is_hazardous(instruction))
        result = self._gateway.execute(instruction.system, instruction.command, args)
        success = bool(getattr(result, "success", False))
        message = str(getattr(result, "message", "") or "")
        values = dict(getattr(result, "values", None) or {})
        self._record(EventKind.COMMAND_RESULT, actor, number, system=instruction.system, command=instruction.command,
                     args=args, success=success, message=message, values=values, result=instruction.result)
        saved = (instruction.result, {"success": success, "message": message, **values}) if instruction.result else None
        if success:
            return Outcome(True, result=saved)
        return Outcome(False, f"{instruction.system}.{instruction.command} failed: {message or 'no message'}", result=saved)

    def _watch(self, subject: Subject, condition: Any, timeout: float, number: str, actor: str) -> Outcome:
        """Watch telemetry until the condition holds (fresh value) or the timeout passes."""
        item = self._sysreps.get(subject.system).telemetry_item(subject.name) if subject.system in self._sysreps else None
        type_name = item.type if item is not None else None
        deadline = time.monotonic() + timeout
        while True:
            self.telemetry_changed.clear()
            reading = self._gateway.telemetry(subject.system, subject.name)
            value, stale = getattr(reading, "value", None), bool(getattr(reading, "stale", False))
            ok = not stale and value is not None and condition.holds(value, type_name)
            remaining = deadline - time.monotonic()
            if ok or remaining <= 0 or self.abort.is_set():
                self._record(EventKind.TELEMETRY_SEEN, actor, number, system=subject.system, item=subject.name,
                             value=value, stale=stale, timestamp=getattr(reading, "timestamp", None),
                             condition=condition.describe(), ok=ok)
                if ok:
                    return Outcome(True)
                if self.abort.is_set():
                    return Outcome(False, "the run was stopped while watching telemetry")
                state = "stale " if stale else ""
                return Outcome(False, f"{subject.describe()} was {state}{value!r}, expected {condition.describe()} "
                                       f"(waited {timeout:g} s)")
            self.telemetry_changed.wait(min(_TELEMETRY_POLL_S, remaining))

    def _read(self, env: dict[str, Any], subject: Subject, number: str, actor: str) -> Any:
        if subject.source == "telemetry":
            reading = self._gateway.telemetry(subject.system, subject.name)
            value = getattr(reading, "value", None)
            self._record(EventKind.TELEMETRY_SEEN, actor, number, system=subject.system, item=subject.name, value=value,
                         stale=bool(getattr(reading, "stale", False)), timestamp=getattr(reading, "timestamp", None))
            if getattr(reading, "stale", False):
                raise KeyError(f"{subject.describe()} is stale; cannot decide the branch")
            return value
        return lookup(env, Reference(subject.name, subject.field if subject.source == "result" else None))

    def _type_of(self, procedure: Procedure, subject: Subject) -> str | None:
        if subject.source == "telemetry":
            sysrep = self._sysreps.get(subject.system)
            item = sysrep.telemetry_item(subject.name) if sysrep is not None else None
            return item.type if item is not None else None
        if subject.source == "result":
            return "boolean" if subject.field == "success" else None
        record = next((i for i in procedure.instructions if isinstance(i, RecordInstruction) and i.name == subject.name), None)
        if record is not None:
            return record.type
        declared = next((i for i in procedure.inputs if i.name == subject.name), None)
        return declared.type if declared is not None else None
