"""How PAX carries out an instruction on the systems: send commands, watch and read telemetry.

The executive (:mod:`pride.executive`) decides *what* runs and *when*; this module does the
blocking part, on PAX's thread and without the executive's lock: a command waits for the
system's answer, a verify or wait watches telemetry until its condition holds or its timeout
passes. Everything it sends and every telemetry value it decides on is recorded through the
``record`` callback before it acts on it.

Command arguments are not checked here: lint typed the values written in the procedure and
checked the types of bound ones, and the gateway checks every value it is sent (the Java host is
authoritative; see :meth:`pride.pax_host.PaxHost.execute`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from pride.events import EventKind
from pride.lint import CheckedProcedure
from pride.model import (
    BranchInstruction,
    CallInstruction,
    CommandInstruction,
    Condition,
    GoToInstruction,
    Instruction,
    Procedure,
    RecordInstruction,
    Reference,
    Subject,
    VerifyInstruction,
    WaitInstruction,
    lookup,
)
from pride.states import OperatorActionError
from pride.sysrep import check_value
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

    def __init__(self, gateway: SystemGateway, checked: CheckedProcedure, record: Callable[..., None]) -> None:
        """``record(kind, actor, number, **data)`` stores an event (the executive's, taking its lock)."""
        self._gateway = gateway
        self._checked = checked
        self._sysreps = checked.sysreps
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

    def carry_out(
        self, env: dict[str, Any], procedure: Procedure, instruction: Instruction, number: str, actor: str
    ) -> Outcome:
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
            if instruction.subject is None or instruction.condition is None:  # the parser refuses this
                raise OperatorActionError(f"{number}: a wait needs seconds or a telemetry condition")
            return self._watch(instruction.subject, instruction.condition, instruction.timeout, number, actor)
        if isinstance(instruction, BranchInstruction):
            value = self._read(env, instruction.subject, number, actor)
            holds = instruction.condition.holds(value, self._type_of(procedure, instruction.subject))
            return Outcome(True, goto=instruction.goto if holds else instruction.else_goto)
        if isinstance(instruction, GoToInstruction):
            return Outcome(True, goto=instruction.step)
        if isinstance(instruction, CallInstruction):
            callee = self._checked.load(instruction.resolved_path)
            declared = {i.name: i.type for i in callee.inputs}
            inputs = {
                a.name: check_value(a.name, declared.get(a.name, "string"), a.value.resolve(env))
                for a in instruction.args
            }
            return Outcome(True, enter=(callee, inputs))
        raise OperatorActionError(f"{number} is performed by an operator")

    def _send(self, env: dict[str, Any], instruction: CommandInstruction, number: str, actor: str) -> Outcome:
        args = {binding.name: self._checked.argument(binding, env) for binding in instruction.args}
        self._record(
            EventKind.COMMAND_SENT,
            actor,
            number,
            system=instruction.system,
            command=instruction.command,
            args=args,
            hazardous=self.is_hazardous(instruction),
        )
        result = self._gateway.execute(instruction.system, instruction.command, args)
        success, message, values = result.success, result.message, dict(result.values)
        self._record(
            EventKind.COMMAND_RESULT,
            actor,
            number,
            system=instruction.system,
            command=instruction.command,
            args=args,
            success=success,
            message=message,
            values=values,
            result=instruction.result,
        )
        saved = (instruction.result, {"success": success, "message": message, **values}) if instruction.result else None
        if success:
            return Outcome(True, result=saved)
        return Outcome(
            False, f"{instruction.system}.{instruction.command} failed: {message or 'no message'}", result=saved
        )

    def _watch(self, subject: Subject, condition: Condition, timeout: float, number: str, actor: str) -> Outcome:
        """Watch telemetry until the condition holds (fresh value) or the timeout passes."""
        system = _system_of(subject)
        type_name = self._telemetry_type(subject)
        deadline = time.monotonic() + timeout
        while True:
            self.telemetry_changed.clear()
            reading = self._gateway.telemetry(system, subject.name)
            value, stale = reading.value, reading.stale
            ok = not stale and value is not None and condition.holds(value, type_name)
            remaining = deadline - time.monotonic()
            if ok or remaining <= 0 or self.abort.is_set():
                self._record(
                    EventKind.TELEMETRY_SEEN,
                    actor,
                    number,
                    system=system,
                    item=subject.name,
                    value=value,
                    stale=stale,
                    timestamp=reading.timestamp,
                    condition=condition.describe(),
                    ok=ok,
                )
                if ok:
                    return Outcome(True)
                if self.abort.is_set():
                    return Outcome(False, "the run was stopped while watching telemetry")
                state = "stale " if stale else ""
                return Outcome(
                    False,
                    f"{subject.describe()} was {state}{value!r}, expected {condition.describe()} "
                    f"(waited {timeout:g} s)",
                )
            self.telemetry_changed.wait(min(_TELEMETRY_POLL_S, remaining))

    def _read(self, env: dict[str, Any], subject: Subject, number: str, actor: str) -> Any:
        if subject.source == "telemetry":
            reading = self._gateway.telemetry(_system_of(subject), subject.name)
            self._record(
                EventKind.TELEMETRY_SEEN,
                actor,
                number,
                system=subject.system,
                item=subject.name,
                value=reading.value,
                stale=reading.stale,
                timestamp=reading.timestamp,
            )
            if reading.stale:
                raise KeyError(f"{subject.describe()} is stale; cannot decide the branch")
            return reading.value
        return lookup(env, Reference(subject.name, subject.field if subject.source == "result" else None))

    def _telemetry_type(self, subject: Subject) -> str | None:
        sysrep = self._sysreps.get(_system_of(subject))
        item = sysrep.telemetry_item(subject.name) if sysrep is not None else None
        return item.type if item is not None else None

    def _type_of(self, procedure: Procedure, subject: Subject) -> str | None:
        if subject.source == "telemetry":
            return self._telemetry_type(subject)
        if subject.source == "result":
            return "boolean" if subject.field == "success" else None
        record = next(
            (i for i in procedure.instructions if isinstance(i, RecordInstruction) and i.name == subject.name), None
        )
        if record is not None:
            return record.type
        declared = next((i for i in procedure.inputs if i.name == subject.name), None)
        return declared.type if declared is not None else None


def _system_of(subject: Subject) -> str:
    """The system of a telemetry subject (the parser gives every telemetry subject one)."""
    if subject.system is None:
        raise KeyError(f"{subject.describe()} names no system")
    return subject.system
