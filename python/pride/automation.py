"""How PAX carries out an instruction on the systems: send commands, watch and read telemetry.

The executive (:mod:`pride.executive`) decides *what* runs and *when*; this module does the
blocking part, on PAX's thread and without the executive's lock: a command waits for the
system's answer, a verify or wait watches telemetry until its condition holds or its timeout
passes. Everything it sends and every telemetry value it decides on is recorded through the
``record`` callback before it acts on it.

Every command carries its key (``run/instruction/attempt``, :func:`command_key`), given by the
executive: a new attempt gets a new key, asking again about an unknown outcome re-sends the same
key. The command's outcome decides the instruction's: SUCCEEDED completes it, FAILED fails it,
UNKNOWN leaves it waiting for an operator (:attr:`InstructionResult.unknown_key`), HALTED (or
any failure while a halt is under way) ends it halted. A halt (:meth:`Automation.request_halt`)
also ends a verify or wait at once.

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

from pride.approvals import command_hazardous
from pride.event_payloads import CommandResult as CommandResultRecord
from pride.event_payloads import CommandSent, TelemetrySeen, ValueSet
from pride.events import Payload
from pride.phrasing import record_refusal
from pride.states import Controller, OperatorActionError, RecordNotCheckable
from pride.systems import CommandResult, Outcome, SystemGateway
from procedure_language.lint import CheckedProcedure
from procedure_language.model import (
    BranchInstruction,
    CallInstruction,
    CommandInstruction,
    Condition,
    GoToInstruction,
    Instruction,
    Procedure,
    RecordInstruction,
    Reference,
    SetInstruction,
    Subject,
    VerifyInstruction,
    WaitInstruction,
    lookup,
)
from procedure_language.sysrep import check_value

__all__ = ["Automation", "ControlLost", "Halt", "InstructionResult", "Send", "command_key"]

_TELEMETRY_POLL_S = 0.25


def command_key(run_id: str, number: str, attempt: int) -> str:
    """The key of one attempt at a command: ``run/instruction/attempt``.

    The instruction part may not contain ``/`` (the key's separator), so the ``/`` of a
    sub-procedure's number (``3.2/1.1``) is written ``:`` (``run-1/3.2:1.1/2``).
    """
    return f"{run_id}/{number.replace('/', ':')}/{attempt}"


@dataclass
class InstructionResult:
    """How an instruction ended: ok or not (with the reason), and where the run goes next."""

    ok: bool
    reason: str = ""
    goto: str | None = None  # a step reference to continue at
    result: tuple[str, Any] | None = None  # a saved command result (name, values) or a set output (name, value)
    enter: tuple[Procedure, dict[str, Any]] | None = None  # a sub-procedure to run, with its inputs
    unknown_key: str | None = None  # its command's outcome is unknown: neither done nor failed
    halted: bool = False  # a halt ended it before it finished


@dataclass(frozen=True)
class Halt:
    """Who halted the run (or stopped it: a stop halts first), and why."""

    user: str
    reason: str


@dataclass(frozen=True)
class Send:
    """How to send the current command: its key, whether that key was sent before, who confirmed it."""

    key: str
    resend: bool = False
    confirmed_by: str | None = None
    requested_by: str | None = None  # under critical commanding: who sent it for approval
    approved_by: str | None = None  # ... and the second operator who approved it


class ControlLost(Exception):
    """The run does not control its robot any more: nothing may be sent (the message says who does)."""

    def __init__(self, message: str, holder: Controller | None) -> None:
        super().__init__(message)
        self.holder = holder


class Automation:
    """Carries out automatable instructions against a gateway for one run."""

    def __init__(
        self,
        gateway: SystemGateway,
        checked: CheckedProcedure,
        record: Callable[[str, str | None, Payload], None],
        *,
        may_send: Callable[[], None],
    ) -> None:
        """``record(actor, number, payload)`` stores an event (the executive's, taking its lock);
        ``may_send()`` raises :class:`ControlLost` when the run must not command its robot."""
        self._gateway = gateway
        self._checked = checked
        self._sysreps = checked.sysreps
        self._record = record
        self._may_send = may_send
        self.telemetry_changed = threading.Event()  # set by the gateway's listener
        self.interrupt = threading.Event()  # set by a halt (or stop): waits and watches end at once
        self._signal_lock = threading.Lock()  # guards _halt and _in_flight: read by halts from any thread
        self._halt: Halt | None = None
        self._in_flight: str | None = None  # the key of the command being sent now

    # ---- halts: called from any thread, never waiting for PAX's thread --------------------------
    def request_halt(self, halt: Halt) -> str | None:
        """Stop what is being performed (no new command leaves); return the key of the command in flight."""
        with self._signal_lock:
            if self._halt is None:
                self._halt = halt
            self.interrupt.set()
            self.telemetry_changed.set()  # a watch wakes now, not at its next poll
            return self._in_flight

    def clear_halt(self) -> None:
        """An operator carries on after a halt."""
        with self._signal_lock:
            self._halt = None
            self.interrupt.clear()

    @property
    def halt(self) -> Halt | None:
        """The halt under way, if any."""
        with self._signal_lock:
            return self._halt

    def light_time(self) -> float:
        """How old telemetry is when it reaches the ground: the link's one-way delay (s)."""
        return self._gateway.one_way_delay()

    def is_hazardous(self, instruction: Instruction) -> bool:
        """Whether an instruction is a command that needs confirmation (marked so, or so in its SysRep)."""
        return command_hazardous(instruction, self._sysreps)

    def check_record(
        self, instruction: RecordInstruction, value: Any
    ) -> tuple[Any, str | None, tuple[str, ...] | None]:
        """A record's value converted and checked (including against the telemetry it names), and what
        its event adds: the ``system.item`` it was checked against and the values listed there
        (None, None: none); OperatorActionError says why a value is refused (RecordNotCheckable:
        the telemetry it must be checked against cannot be read now)."""
        try:
            converted = instruction.check(value)
        except ValueError as exc:
            raise OperatorActionError(str(exc)) from None
        if instruction.one_of_telemetry is None:
            return converted, None, None
        system, item = instruction.one_of_telemetry
        try:
            reading = self._gateway.telemetry(system, item)
        except Exception as exc:
            problem = f"{type(exc).__name__}: {exc}"
            refusal = record_refusal(converted, system, item, self._sysreps, problem=problem)
            raise RecordNotCheckable(refusal, system, item) from None
        if reading.stale or reading.value is None:
            problem = "stale" if reading.value is not None else "missing"
            refusal = record_refusal(converted, system, item, self._sysreps, problem=problem)
            raise RecordNotCheckable(refusal, system, item)
        allowed = [v.strip() for v in str(reading.value).split(",") if v.strip()]
        if str(converted) not in allowed:
            raise OperatorActionError(record_refusal(converted, system, item, self._sysreps, listed=allowed))
        return converted, f"{system}.{item}", tuple(allowed)

    def carry_out(
        self,
        env: dict[str, Any],
        procedure: Procedure,
        instruction: Instruction,
        number: str,
        actor: str,
        send: Send | None = None,
    ) -> InstructionResult:
        """Perform one instruction as ``actor`` (a command as ``send`` says); returns once it has ended."""
        if isinstance(instruction, CommandInstruction):
            if send is None:
                raise OperatorActionError(f"{number}: a command needs its key")  # the executive always gives one
            return self._send(env, instruction, number, actor, send)
        if isinstance(instruction, VerifyInstruction):
            return self._watch(instruction.subject, instruction.condition, instruction.timeout, number, actor)
        if isinstance(instruction, WaitInstruction):
            if instruction.seconds is not None:
                if self.interrupt.wait(instruction.seconds):
                    return self._halted("during the wait")
                return InstructionResult(True)
            if instruction.subject is None or instruction.condition is None:  # the parser refuses this
                raise OperatorActionError(f"{number}: a wait needs seconds or a telemetry condition")
            return self._watch(instruction.subject, instruction.condition, instruction.timeout, number, actor)
        if isinstance(instruction, BranchInstruction):
            value = self._read(env, instruction.subject, number, actor)
            holds = instruction.condition.holds(value, self._type_of(procedure, instruction.subject))
            return InstructionResult(True, goto=instruction.goto if holds else instruction.else_goto)
        if isinstance(instruction, GoToInstruction):
            return InstructionResult(True, goto=instruction.step)
        if isinstance(instruction, SetInstruction):
            return self._set(env, procedure, instruction, number, actor)
        if isinstance(instruction, CallInstruction):
            callee = self._checked.load(instruction.resolved_path)
            declared = {i.name: i.type for i in callee.inputs}
            inputs = {
                a.name: check_value(a.name, declared.get(a.name, "string"), a.value.resolve(env))
                for a in instruction.args
            }
            return InstructionResult(True, enter=(callee, inputs))
        raise OperatorActionError(f"{number} is performed by an operator")

    def _set(
        self, env: dict[str, Any], procedure: Procedure, instruction: SetInstruction, number: str, actor: str
    ) -> InstructionResult:
        """``<set>``: the output gets its value, converted to the output's type, for the caller to read."""
        output_type = next((o.type for o in procedure.outputs if o.name == instruction.name), "string")
        try:
            value = check_value(instruction.name, output_type, instruction.value.resolve(env))
        except (KeyError, ValueError) as exc:  # lint rules both out; a run must still not go on with a wrong value
            return InstructionResult(False, f"cannot set {instruction.name}: {exc.args[0] if exc.args else exc}")
        self._record(actor, number, ValueSet(name=instruction.name, value=value))
        return InstructionResult(True, result=(instruction.name, value))

    def _send(
        self, env: dict[str, Any], instruction: CommandInstruction, number: str, actor: str, send: Send
    ) -> InstructionResult:
        args = {binding.name: self._checked.argument(binding, env) for binding in instruction.args}
        self._may_send()
        hazardous = self.is_hazardous(instruction)
        sent = CommandSent(
            system=instruction.system,
            command=instruction.command,
            args=args,
            key=send.key,
            hazardous=hazardous,
            resend=send.resend,
            confirmed_by=send.confirmed_by if hazardous else None,
            requested_by=send.requested_by if send.approved_by else None,
            approved_by=send.approved_by,
        )
        self._record(actor, number, sent)
        with self._signal_lock:
            halted_first = self._halt is not None
            if not halted_first:
                self._in_flight = send.key
        if halted_first:
            result = CommandResult(Outcome.HALTED, "not sent: the run was halted before it left")
        else:
            try:
                result = self._gateway.execute(instruction.system, instruction.command, args, key=send.key)
            except Exception as exc:  # the gateway refuses before sending (bad argument, unknown command)
                result = CommandResult(Outcome.FAILED, f"not sent: {type(exc).__name__}: {exc}")
            finally:
                with self._signal_lock:
                    self._in_flight = None
        outcome = result.outcome
        success = None if outcome is Outcome.UNKNOWN else result.success  # unknown: neither success nor failure
        answer = CommandResultRecord(
            system=sent.system,
            command=sent.command,
            args=args,
            key=send.key,
            outcome=outcome.value,
            success=success,
            message=result.message,
            values=dict(result.values),
            result=instruction.result,
        )
        self._record(actor, number, answer)
        saved = None
        if instruction.result and outcome is not Outcome.UNKNOWN:
            saved = (instruction.result, {"success": result.success, "message": result.message, **result.values})
        name = f"{instruction.system}.{instruction.command}"
        if outcome is Outcome.SUCCEEDED:
            return InstructionResult(True, result=saved)
        if outcome is Outcome.UNKNOWN:
            return InstructionResult(False, f"outcome of {send.key} unknown: {result.message}", unknown_key=send.key)
        if outcome is Outcome.HALTED or self.halt is not None:
            return InstructionResult(
                False, f"{name} halted: {result.message or 'no message'}", result=saved, halted=True
            )
        return InstructionResult(False, f"{name} failed: {result.message or 'no message'}", result=saved)

    def _halted(self, during: str) -> InstructionResult:
        halt = self.halt
        why = f" by {halt.user}" + (f": {halt.reason}" if halt.reason else "") if halt else ""
        return InstructionResult(False, f"halted {during}{why}", halted=True)

    def _watch(
        self, subject: Subject, condition: Condition, timeout: float, number: str, actor: str
    ) -> InstructionResult:
        """Watch telemetry until the condition holds (fresh value) or the timeout passes.

        The timeout counts the light time too: the procedure's timeout is how long the system may
        take, and what it does reaches the ground one one-way delay later (a value 1.3 s old on a
        1.3 s link is the newest there is). A halt ends the watch at once.
        """
        system = _system_of(subject)
        type_name = self._telemetry_type(subject)
        light = self.light_time()
        deadline = time.monotonic() + timeout + light
        while True:
            self.telemetry_changed.clear()
            reading = self._gateway.telemetry(system, subject.name)
            value, stale = reading.value, reading.stale
            ok = not stale and value is not None and condition.holds(value, type_name)
            remaining = deadline - time.monotonic()
            if ok or remaining <= 0 or self.interrupt.is_set():
                seen = TelemetrySeen(
                    system=system,
                    item=subject.name,
                    value=value,
                    stale=stale,
                    timestamp=reading.timestamp,
                    condition=condition.describe(),
                    ok=ok,
                )
                self._record(actor, number, seen)
                if ok:
                    return InstructionResult(True)
                if self.interrupt.is_set():
                    return self._halted("while watching telemetry")
                state = "stale " if stale else ""
                waited = f"{timeout:g} s" + (f" + {light:g} s light time" if light else "")
                expected = f"expected {condition.describe()} (waited {waited})"
                return InstructionResult(False, f"{subject.describe()} was {state}{value!r}, {expected}")
            self.telemetry_changed.wait(min(_TELEMETRY_POLL_S, remaining))

    def _read(self, env: dict[str, Any], subject: Subject, number: str, actor: str) -> Any:
        if subject.source == "telemetry":
            reading = self._gateway.telemetry(_system_of(subject), subject.name)
            seen = TelemetrySeen(
                system=subject.system,
                item=subject.name,
                value=reading.value,
                stale=reading.stale,
                timestamp=reading.timestamp,
            )
            self._record(actor, number, seen)
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
