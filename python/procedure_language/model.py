"""The procedure model: procedure → numbered steps → numbered instructions.

Built by :mod:`procedure_language.parser` from XML, checked by :mod:`procedure_language.lint`, run by
:mod:`pride.executive`. Every node keeps the file position it came from so lint errors and
runtime failures can point at the line an author must fix. Steps are numbered 1, 2, …;
instructions 1.1, 1.2, … in document order; notes, cautions and warnings are not numbered and
travel with the instruction that follows them.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

from procedure_language.limits import Persistence
from procedure_language.sysrep import check_value

__all__ = [
    "ArgumentBinding",
    "BranchInstruction",
    "CallInstruction",
    "CommandInstruction",
    "Condition",
    "GoToInstruction",
    "Input",
    "Instruction",
    "Kind",
    "Location",
    "ManualInstruction",
    "Monitor",
    "Notice",
    "Output",
    "Procedure",
    "RecordInstruction",
    "Reference",
    "RespondsTo",
    "SetInstruction",
    "Step",
    "Subject",
    "Template",
    "VerifyInstruction",
    "WaitInstruction",
]


@dataclass(frozen=True, order=True)
class Location:
    """A position in a procedure file, printed as ``file:line:col``."""

    path: str
    line: int
    col: int

    def __str__(self) -> str:
        return f"{self.path}:{self.line}:{self.col}"


class Kind(enum.Enum):
    """What an instruction asks for."""

    COMMAND = "command"
    """Send a SysRep command."""
    VERIFY = "verify"
    """Check that telemetry meets a condition within a timeout."""
    WAIT = "wait"
    """Wait a duration, or until telemetry meets a condition."""
    RECORD = "record"
    """The operator enters a typed value."""
    MANUAL = "manual"
    """The operator does something and marks it done."""
    BRANCH = "if"
    """Go to a step when a condition holds (optionally to another when it does not)."""
    GOTO = "goto"
    """Continue at another step."""
    CALL = "call"
    """Run a sub-procedure, then continue."""
    SET = "set"
    """Set an output of this procedure, which its caller reads."""


_REFERENCE = re.compile(r"\$\{([A-Za-z_][A-Za-z0-9_]*)(?:\.([A-Za-z_][A-Za-z0-9_]*))?\}")


@dataclass(frozen=True)
class Reference:
    """``${name}`` (a recorded input) or ``${name.field}`` (a value of a saved command result, or
    an output of a called sub-procedure)."""

    name: str
    field: str | None = None

    def __str__(self) -> str:
        return f"${{{self.name}.{self.field}}}" if self.field else f"${{{self.name}}}"


@dataclass(frozen=True)
class Template:
    """An argument value: literal text with ``${...}`` references filled in at run time."""

    parts: tuple[str | Reference, ...]

    @staticmethod
    def parse(text: str) -> Template:
        parts: list[str | Reference] = []
        pos = 0
        for match in _REFERENCE.finditer(text):
            if match.start() > pos:
                parts.append(text[pos : match.start()])
            parts.append(Reference(match.group(1), match.group(2)))
            pos = match.end()
        if pos < len(text) or not parts:
            parts.append(text[pos:])
        return Template(tuple(parts))

    @property
    def references(self) -> tuple[Reference, ...]:
        return tuple(p for p in self.parts if isinstance(p, Reference))

    @property
    def whole_reference(self) -> Reference | None:
        """The reference when the value is exactly one ``${...}`` (its value keeps its type)."""
        return self.parts[0] if len(self.parts) == 1 and isinstance(self.parts[0], Reference) else None

    def resolve(self, env: dict[str, Any]) -> Any:
        """Fill in references from ``env``; raise KeyError naming what is unbound."""
        whole = self.whole_reference
        if whole is not None:
            return lookup(env, whole)
        return self.fill(env, strict=True)

    def fill(
        self,
        env: dict[str, Any],
        show: Callable[[Any], str] | None = None,
        *,
        strict: bool = False,
        unknown: Callable[[Reference], str] = str,
    ) -> str:
        """The text with the references ``env`` binds filled in, each value written by ``show``
        (plain text by default). One not bound yet is written by ``unknown`` (as ``${...}`` by
        default: an author reads the text as written), or raises KeyError if ``strict``."""
        write = show or _text
        texts: list[str] = []
        for part in self.parts:
            if isinstance(part, str):
                texts.append(part)
                continue
            try:
                texts.append(write(lookup(env, part)))
            except KeyError:
                if strict:
                    raise
                texts.append(unknown(part))
        return "".join(texts)

    def __str__(self) -> str:
        return "".join(str(p) for p in self.parts)


def lookup(env: dict[str, Any], ref: Reference) -> Any:
    """The value of a reference in a run's variables; KeyError says which name is missing."""
    if ref.name not in env:
        raise KeyError(f"{ref} is not bound (no input or result named {ref.name!r} yet)")
    value = env[ref.name]
    if ref.field is None:
        return value
    if not isinstance(value, dict) or ref.field not in value:
        raise KeyError(f"{ref}: result {ref.name!r} has no value {ref.field!r}")
    return value[ref.field]


def _text(value: Any) -> str:
    return ("true" if value else "false") if isinstance(value, bool) else str(value)


@dataclass(frozen=True)
class Condition:
    """A test on one value: equals (± tolerance), differs, and/or a min..max range."""

    equals: str | None = None
    not_equals: str | None = None
    minimum: str | None = None
    maximum: str | None = None
    tolerance: float | None = None

    def describe(self) -> str:
        parts = []
        if self.equals is not None:
            parts.append(f"= {self.equals}" + (f" ± {self.tolerance:g}" if self.tolerance is not None else ""))
        if self.not_equals is not None:
            parts.append(f"≠ {self.not_equals}")
        if self.minimum is not None:
            parts.append(f"≥ {self.minimum}")
        if self.maximum is not None:
            parts.append(f"≤ {self.maximum}")
        return " and ".join(parts)

    def holds(self, value: Any, type_name: str | None) -> bool:
        """Whether ``value`` meets the condition, comparing as ``type_name`` (guessed when None)."""
        kind = type_name or _guess_type(value)
        try:
            actual = check_value("value", kind, value)
        except ValueError:
            return False
        if self.equals is not None:
            expected = check_value("equals", kind, self.equals)
            if self.tolerance is not None and kind in ("integer", "real"):
                if abs(actual - expected) > self.tolerance:
                    return False
            elif actual != expected:
                return False
        if self.not_equals is not None and actual == check_value("not-equals", kind, self.not_equals):
            return False
        if self.minimum is not None and actual < check_value("min", kind, self.minimum):
            return False
        return self.maximum is None or actual <= check_value("max", kind, self.maximum)


def _guess_type(value: Any) -> str:
    if isinstance(value, bool):
        return "boolean"
    if isinstance(value, int):
        return "integer"
    if isinstance(value, float):
        return "real"
    return "string"


@dataclass(frozen=True)
class Subject:
    """What a condition reads: telemetry of a system, a recorded input, or a saved command result."""

    source: str  # "telemetry" | "input" | "result"
    name: str
    system: str | None = None
    field: str | None = None

    def describe(self) -> str:
        if self.source == "telemetry":
            return f"{self.system}.{self.name}"
        if self.source == "result":
            return f"result {self.name}.{self.field}"
        return f"input {self.name}"


@dataclass(frozen=True)
class Notice:
    """A note, caution or warning shown to the operator with the instruction that follows it."""

    level: str
    text: str
    where: Location


@dataclass(frozen=True)
class ArgumentBinding:
    """One ``<arg name="...">value</arg>`` of a command or call."""

    name: str
    value: Template
    where: Location


@dataclass(frozen=True, kw_only=True)
class Instruction:
    """One numbered instruction. ``attrs`` maps attribute names to where they are, for lint messages."""

    number: str
    kind: Kind
    text: str
    automatable: bool
    where: Location
    notices: tuple[Notice, ...] = ()
    attrs: dict[str, Location] = field(default_factory=dict, compare=False, hash=False)

    def at(self, attribute: str) -> Location:
        """Where ``attribute`` is written (the element itself when it is absent)."""
        return self.attrs.get(attribute, self.where)

    @property
    def needs_operator(self) -> bool:
        """Whether only an operator can complete it (records, manual actions, non-automatable ones)."""
        return self.kind in (Kind.RECORD, Kind.MANUAL) or not self.automatable

    def describe(self) -> str:
        return self.text


@dataclass(frozen=True, kw_only=True)
class CommandInstruction(Instruction):
    system: str
    command: str
    args: tuple[ArgumentBinding, ...]
    result: str | None = None
    hazardous: bool = False
    on_failure: str | None = None

    def describe(self) -> str:
        args = ", ".join(f"{a.name}={a.value}" for a in self.args)
        return self.text or f"Send {self.system}.{self.command}({args})"


@dataclass(frozen=True, kw_only=True)
class VerifyInstruction(Instruction):
    subject: Subject
    condition: Condition
    timeout: float
    on_failure: str | None = None

    def describe(self) -> str:
        return self.text or f"Verify {self.subject.describe()} {self.condition.describe()} (within {self.timeout:g} s)"


@dataclass(frozen=True, kw_only=True)
class WaitInstruction(Instruction):
    seconds: float | None = None
    subject: Subject | None = None
    condition: Condition | None = None
    timeout: float = 60.0
    on_failure: str | None = None

    def describe(self) -> str:
        if self.text:
            return self.text
        if self.subject is not None and self.condition is not None:
            return f"Wait until {self.subject.describe()} {self.condition.describe()} (at most {self.timeout:g} s)"
        return f"Wait {self.seconds:g} s"


@dataclass(frozen=True, kw_only=True)
class RecordInstruction(Instruction):
    name: str
    type: str
    minimum: float | None = None
    maximum: float | None = None
    pattern: str | None = None
    choices: tuple[str, ...] | None = None
    #: (system, item): a telemetry item listing the acceptable values, comma-separated; checked
    #: when the value is entered, against the value the system reports then (the executive does it)
    one_of_telemetry: tuple[str, str] | None = None

    def check(self, value: Any) -> Any:
        """The entered value converted to this record's type, or ValueError saying what is wrong."""
        enum = tuple(check_value(self.name, self.type, c) for c in self.choices) if self.choices else None
        converted = check_value(self.name, self.type, value, self.minimum, self.maximum, enum)
        if self.pattern is not None and not re.fullmatch(self.pattern, str(converted)):
            raise ValueError(f"{self.name}: {converted!r} does not match the pattern {self.pattern}")
        return converted


@dataclass(frozen=True, kw_only=True)
class ManualInstruction(Instruction):
    pass


@dataclass(frozen=True, kw_only=True)
class BranchInstruction(Instruction):
    subject: Subject
    condition: Condition
    goto: str
    else_goto: str | None = None

    def describe(self) -> str:
        otherwise = f", else go to step {self.else_goto}" if self.else_goto else ""
        test = f"{self.subject.describe()} {self.condition.describe()}"
        return self.text or f"If {test}, go to step {self.goto}{otherwise}"


@dataclass(frozen=True, kw_only=True)
class GoToInstruction(Instruction):
    step: str

    def describe(self) -> str:
        return self.text or f"Go to step {self.step}"


@dataclass(frozen=True, kw_only=True)
class CallInstruction(Instruction):
    procedure: str  # file path as written, relative to the calling procedure
    args: tuple[ArgumentBinding, ...]
    resolved_path: str = ""
    result: str | None = None  # the name the caller reads the callee's outputs under: ${result.output}

    def describe(self) -> str:
        return self.text or f"Run sub-procedure {self.procedure}"


@dataclass(frozen=True, kw_only=True)
class SetInstruction(Instruction):
    """``<set name="x">${located.x}</set>``: sets output ``x`` of this procedure for its caller."""

    name: str
    value: Template

    def describe(self) -> str:
        return self.text or f"Set {self.name} to {self.value}"


@dataclass(frozen=True, kw_only=True)
class Monitor:
    """A condition watched on every telemetry update while it is active, whatever instruction runs:
    ``<monitor system=... telemetry=... (min|max|equals|not-equals | limit="red|yellow")>``.

    Active while the run is in its step (``scope="step"``), or from its step to the run's end
    (``scope="procedure"``). Out of its condition (or its SysRep limits at ``limit`` or worse) for
    its ``persistence``, it is violated: the run holds, halts, or halts and goes to step ``goto``
    (``on_violation``: ``hold``, ``halt``, ``goto``).
    """

    system: str
    telemetry: str
    condition: Condition | None
    limit: str | None
    scope: str
    on_violation: str
    goto: str | None
    persistence: Persistence | None  # None: as the item's SysRep limits say (one sample without them)
    text: str
    step: int
    where: Location
    attrs: dict[str, Location] = field(default_factory=dict, compare=False, hash=False)

    def at(self, attribute: str) -> Location:
        return self.attrs.get(attribute, self.where)

    @property
    def name(self) -> str:
        """How the record and the console name it: its item and step."""
        return f"{self.system}.{self.telemetry} (step {self.step})"

    def describe(self) -> str:
        watched = self.condition.describe() if self.condition is not None else f"within its {self.limit} limits"
        return self.text or f"{self.system}.{self.telemetry} {watched}"


@dataclass(frozen=True, kw_only=True)
class RespondsTo:
    """An anomaly the procedure answers: ``<responds-to system=... telemetry=... limit="red|yellow">``
    with the reason as its text. The item at its SysRep limits of that colour or worse (as a
    monitor's ``limit`` reads them) is what this procedure is for, so whoever watches telemetry,
    an operator or an agent, can find it. Declared, never watched: nothing starts a run by itself.
    """

    system: str
    telemetry: str
    limit: str
    text: str
    where: Location
    attrs: dict[str, Location] = field(default_factory=dict, compare=False, hash=False)

    def at(self, attribute: str) -> Location:
        return self.attrs.get(attribute, self.where)


@dataclass(frozen=True)
class Step:
    """A numbered step: a title and its instructions. ``id`` is what go-tos name."""

    number: int
    id: str
    title: str
    instructions: tuple[Instruction, ...]
    where: Location
    notices: tuple[Notice, ...] = ()
    contingency: bool = False
    monitors: tuple[Monitor, ...] = ()


@dataclass(frozen=True)
class Input:
    """A value a caller passes into a (sub-)procedure: ``<input name="..." type="..."/>``."""

    name: str
    type: str
    where: Location


@dataclass(frozen=True)
class Output:
    """A value a sub-procedure hands back to its caller: ``<output name="..." type="..."/>``."""

    name: str
    type: str
    where: Location


@dataclass(frozen=True)
class Procedure:
    """One procedure file."""

    id: str
    title: str
    version: str
    path: str
    uses: tuple[tuple[str, Location], ...]
    inputs: tuple[Input, ...]
    steps: tuple[Step, ...]
    where: Location
    description: str = ""
    outputs: tuple[Output, ...] = ()
    responds_to: tuple[RespondsTo, ...] = ()

    @cached_property
    def instructions(self) -> tuple[Instruction, ...]:
        return tuple(i for s in self.steps for i in s.instructions)

    def following(self, index: int) -> int:
        """The index of the instruction after ``instructions[index]`` when nothing branches.

        Contingency steps (``<step contingency="true">``) are entered only by a go-to or branch:
        the flow passes over them, so off-nominal handling can sit after the last nominal step.
        """
        flat = self.instructions
        step = flat[index].number.split(".")[0]
        n = index + 1
        while n < len(flat) and flat[n].number.split(".")[0] != step and self.step_of(flat[n].number).contingency:
            n += len(self.step_of(flat[n].number).instructions)
        return n

    def step(self, ref: str) -> Step | None:
        """The step named by a go-to: its id, or its number."""
        for s in self.steps:
            if s.id == ref or str(s.number) == ref:
                return s
        return None

    def instruction(self, number: str) -> Instruction | None:
        return next((i for i in self.instructions if i.number == number), None)

    def step_of(self, number: str) -> Step:
        return self.steps[int(number.split(".")[0]) - 1]
