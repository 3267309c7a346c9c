"""Meaning checks of a procedure against its SysReps: what ``caretaker lint`` reports.

After the schema and structure (:mod:`procedure_language.parser`), lint checks that every system, command,
telemetry item and argument exists with the right type, that every ``${...}`` is bound on every
path that reaches it, that go-tos land on a step, that every step can be reached, and that
sub-procedure calls pass what the callee declares. A procedure with any problem does not start.

A run checks its procedure once: :func:`check_procedure` parses and lints the procedure and every
sub-procedure it calls (each file once, however often it is called) and returns a
:class:`CheckedProcedure`, which is what the executive runs. Literal argument values are
converted to their SysRep types here, so a run sends typed values without checking them again.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any, Protocol

from procedure_language.diagnostics import Problem, ProcedureError
from procedure_language.model import (
    ArgumentBinding,
    BranchInstruction,
    CallInstruction,
    CommandInstruction,
    Condition,
    GoToInstruction,
    Instruction,
    Location,
    Monitor,
    Procedure,
    RecordInstruction,
    Reference,
    SetInstruction,
    Subject,
    Template,
    VerifyInstruction,
    WaitInstruction,
)
from procedure_language.parser import parse_procedure
from procedure_language.sysrep import SysRep, Telemetry, check_value

__all__ = ["CheckedProcedure", "Unbound", "check_procedure", "lint_file", "section_needs"]


_UNTYPED = object()  # check_value's answer for a value known only at run time, or wrong


class _Placed(Protocol):
    """What lint can point at: an instruction or a monitor, each attribute where it is written."""

    def at(self, attribute: str) -> Location: ...


@dataclass(frozen=True)
class _Variable:
    """A name a procedure defines: an input, record or output (a typed value), a saved command
    result, or a called sub-procedure's outputs."""

    name: str
    source: str  # "input" | "record" | "output" | "result" | "call"
    type: str | None
    where: Location


@dataclass(frozen=True)
class CheckedProcedure:
    """A procedure that passed lint against ``sysreps``, with every sub-procedure it calls.

    Only :func:`check_procedure` makes one, so holding one means no problem was found. A run
    executes exactly what was checked: a sub-procedure edited on disk after the check does not
    change it.
    """

    procedure: Procedure
    sysreps: Mapping[str, SysRep]
    callees: Mapping[str, Procedure]  # resolved path → procedure
    literals: Mapping[ArgumentBinding, Any]  # a command argument written as text → its typed value

    def load(self, path: str) -> Procedure:
        """A called sub-procedure, by its resolved path (as checked, not read again)."""
        return self.callees[path]

    def argument(self, binding: ArgumentBinding, env: dict[str, Any]) -> Any:
        """The value of a command argument in a run: typed when written as text, else resolved."""
        return self.literals[binding] if binding in self.literals else binding.value.resolve(env)


def lint_file(path: str | Path, sysreps: Mapping[str, SysRep]) -> list[Problem]:
    """Every problem of one procedure file (and of the sub-procedures it calls)."""
    return _Session(sysreps).lint(Path(path), frozenset())[1]


def check_procedure(path: str | Path, sysreps: Mapping[str, SysRep]) -> CheckedProcedure:
    """Parse and lint a procedure and its sub-procedures once, for a run.

    Raises:
        ProcedureError: listing every problem; a procedure with any problem does not run.
    """
    session = _Session(sysreps)
    procedure, problems = session.lint(Path(path), frozenset())
    if procedure is None or problems:
        raise ProcedureError(problems)
    callees = {p: c for p, (c, _) in session.done.items() if c is not None and c is not procedure}
    return CheckedProcedure(
        procedure, MappingProxyType(dict(sysreps)), MappingProxyType(callees), MappingProxyType(session.literals)
    )


@dataclass(frozen=True)
class Unbound:
    """A value a run started at a step needs but never bound: ``name`` or ``name.field``, and where it is read."""

    name: str
    where: Location

    def __str__(self) -> str:
        return f"{self.where}: {self.name}"


def section_needs(checked: CheckedProcedure, start_step: str, given: Collection[str] = ()) -> list[Unbound]:
    """What a run started at ``start_step`` reads that only the part it skips would have bound, less
    what ``given`` names (``name``, or ``name.field`` of a result, as ``caretaker run --set`` gives
    them): each once, where it is first read.

    Raises:
        KeyError: the procedure has no step ``start_step``.
    """
    procedure = checked.procedure
    step = procedure.step(start_step)
    if step is None:
        raise KeyError(f"no step {start_step!r} (steps: {', '.join(s.id for s in procedure.steps)})")
    linter = _Linter(procedure, _Session(checked.sysreps), frozenset())
    linter.collect_variables()
    start = linter.index[step.instructions[0].number]
    successors = linter.control_flow()
    reachable = linter.reached_from(successors, start)
    defined_in = linter.defined_before(successors, reachable, start, frozenset(i.name for i in procedure.inputs))
    needs: dict[str, Unbound] = {}
    for n in sorted(reachable):
        for ref, where in linter.uses(linter.flat[n]):
            name = f"{ref.name}.{ref.field}" if ref.field else ref.name
            bound = ref.name in defined_in[n] or name in given
            if ref.name in linter.variables and not bound:
                needs.setdefault(name, Unbound(name, where))
    return list(needs.values())


@dataclass
class _Session:
    """One lint of a procedure tree: each file is parsed and linted once, however often it is called."""

    sysreps: Mapping[str, SysRep]
    done: dict[str, tuple[Procedure | None, list[Problem]]] = field(default_factory=dict)
    literals: dict[ArgumentBinding, Any] = field(default_factory=dict)

    def lint(self, path: Path, seen: frozenset[str]) -> tuple[Procedure | None, list[Problem]]:
        """The parsed procedure (None when it has structural errors) and every problem of it.

        Problems name ``path`` as given; files are told apart by their resolved path.
        """
        key = str(path.resolve())
        if key not in self.done:
            procedure, problems = parse_procedure(path)
            if procedure is not None:
                problems = list(dict.fromkeys(_Linter(procedure, self, seen | {key}).run()))
            self.done[key] = procedure, problems
        return self.done[key]


class _Linter:
    def __init__(self, procedure: Procedure, session: _Session, seen: frozenset[str]) -> None:
        self.proc = procedure
        self.session = session
        self.sysreps = session.sysreps
        self.seen = seen
        self.problems: list[Problem] = []
        self.flat = procedure.instructions
        self.index = {i.number: n for n, i in enumerate(self.flat)}
        self.variables: dict[str, _Variable] = {}
        self.call_outputs: dict[str, tuple[str, dict[str, str]]] = {}  # call result → (callee id, output types)

    def fail(self, where: Location, message: str) -> None:
        self.problems.append(Problem(where, message))

    def run(self) -> list[Problem]:
        declared = set()
        for system, where in self.proc.uses:
            if system not in self.sysreps:
                known = ", ".join(sorted(self.sysreps)) or "none"
                self.fail(where, f"unknown system {system!r} (known SysReps: {known})")
            declared.add(system)
        self.declared = declared
        for response in self.proc.responds_to:
            advice = "name an item with limits, or give this one limits there: {yellow_high: ..., red_high: ...}"
            self.check_limits(response, response.system, response.telemetry, response.limit, advice)
        self.collect_variables()
        for instruction in self.flat:
            self.check(instruction)
        for monitor in (m for step in self.proc.steps for m in step.monitors):
            self.check_monitor(monitor)
        successors = self.control_flow()
        reachable = self.reachability(successors)
        self.check_variables(successors, reachable)
        return self.problems

    # ---- names ------------------------------------------------------------------------------
    def collect_variables(self) -> None:
        defs: list[_Variable] = [_Variable(i.name, "input", i.type, i.where) for i in self.proc.inputs]
        defs += [_Variable(o.name, "output", o.type, o.where) for o in self.proc.outputs]
        for i in self.flat:
            if isinstance(i, RecordInstruction):
                defs.append(_Variable(i.name, "record", i.type, i.at("name")))
            elif isinstance(i, CommandInstruction) and i.result:
                defs.append(_Variable(i.result, "result", None, i.at("result")))
            elif isinstance(i, CallInstruction) and i.result:
                defs.append(_Variable(i.result, "call", None, i.at("result")))
        for var in defs:
            first = self.variables.get(var.name)
            if first is None:
                self.variables[var.name] = var
            elif first.source != var.source or first.type != var.type:
                self.fail(
                    var.where,
                    f"{var.name!r} is already a {first.source}"
                    f"{' of type ' + first.type if first.type else ''} (line {first.where.line}); use another name",
                )

    def system(self, placed: _Placed, system: str | None, attribute: str = "system") -> SysRep | None:
        """The SysRep of a system the procedure uses; None once it said at ``attribute`` that it is unknown."""
        where = placed.at(attribute)
        if system is None or system not in self.sysreps:
            known = ", ".join(sorted(self.sysreps)) or "none"
            self.fail(where, f"unknown system {system!r} (known SysReps: {known})")
            return None
        if system not in self.declared:
            self.fail(where, f'system {system!r} is not declared; add <uses system="{system}"/> to the procedure')
        return self.sysreps[system]

    def item(self, placed: _Placed, system: str | None, item_id: str, attribute: str = "telemetry") -> Telemetry | None:
        """The telemetry item ``system.item_id``; None once it said which name is unknown (the system at
        its own attribute, unless ``attribute`` names both, as one-of-telemetry does)."""
        sysrep = self.system(placed, system, "system" if attribute == "telemetry" else attribute)
        item = sysrep.telemetry_item(item_id) if sysrep is not None else None
        if sysrep is not None and item is None:
            known = ", ".join(t.id for t in sysrep.telemetry)
            self.fail(placed.at(attribute), f"unknown telemetry {item_id!r} in {system} (telemetry: {known})")
        return item

    def check_limits(self, placed: _Placed, system: str, item_id: str, limit: str | None, advice: str) -> None:
        """The item has SysRep limits of the colour ``limit`` names (an equals limit has only red);
        ``advice`` says what to do about an item without limits."""
        item = self.item(placed, system, item_id)
        if item is None:
            return
        if item.limits is None:
            path = self.sysreps[system].path
            self.fail(placed.at("limit"), f"{system}.{item_id} has no limits in its SysRep ({path}): {advice}")
        elif limit == "yellow" and item.limits.equals is not None:
            self.fail(placed.at("limit"), f"{system}.{item_id}'s limit is an equals: it has no yellow band; use red")

    def step_target(self, instruction: _Placed, attribute: str, ref: str | None) -> None:
        if ref is not None and self.proc.step(ref) is None:
            known = ", ".join(s.id for s in self.proc.steps)
            self.fail(instruction.at(attribute), f"go-to to nowhere: no step {ref!r} (steps: {known})")

    # ---- instructions -----------------------------------------------------------------------
    def check(self, i: Instruction) -> None:
        if isinstance(i, CommandInstruction):
            self.check_command(i)
            self.step_target(i, "on-failure", i.on_failure)
        elif isinstance(i, (VerifyInstruction, WaitInstruction, BranchInstruction)):
            if i.subject is not None and i.condition is not None:
                self.check_condition(i, i.subject, i.condition)
            if isinstance(i, BranchInstruction):
                self.step_target(i, "goto", i.goto)
                self.step_target(i, "else", i.else_goto)
            else:
                self.step_target(i, "on-failure", i.on_failure)
        elif isinstance(i, GoToInstruction):
            self.step_target(i, "step", i.step)
        elif isinstance(i, CallInstruction):
            self.check_call(i)
        elif isinstance(i, SetInstruction):
            self.check_set(i)
        elif isinstance(i, RecordInstruction) and i.one_of_telemetry is not None:
            self.check_listed_values(i, *i.one_of_telemetry)

    def check_monitor(self, m: Monitor) -> None:
        """A monitor watches an item its SysRep has: its condition fits the item's type, or the item
        has the limits it names; a go-to on violation lands on a step."""
        if m.on_violation == "goto":
            self.step_target(m, "on-violation", m.goto)
        if m.condition is not None:
            self.check_condition(m, Subject("telemetry", m.telemetry, system=m.system), m.condition)
        else:
            advice = "watch a condition (min, max, equals) or give the item limits: {red_high: ...}"
            self.check_limits(m, m.system, m.telemetry, m.limit, advice)

    def check_set(self, i: SetInstruction) -> None:
        """``<set>`` names a declared output, and its value fits the output's type."""
        output = next((o for o in self.proc.outputs if o.name == i.name), None)
        if output is None:
            declared = ", ".join(o.name for o in self.proc.outputs) or "none"
            self.fail(
                i.at("name"),
                f"<set> names no output of {self.proc.id}: {i.name!r} (declared outputs: {declared}; "
                f'declare it with <output name="{i.name}" type="..."/>)',
            )
            return
        binding = ArgumentBinding(i.name, i.value, i.at("value"))
        self.check_value(
            binding, output.type, f"output {i.name!r}", functools.partial(check_value, i.name, output.type)
        )

    def check_listed_values(self, i: RecordInstruction, system: str, item_id: str) -> None:
        """``one-of-telemetry``: a string item of a used system that lists the acceptable values."""
        item = self.item(i, system, item_id, "one-of-telemetry")
        if item is not None and item.type != "string":
            self.fail(
                i.at("one-of-telemetry"),
                f"one-of-telemetry needs a string item listing the values (comma-separated); "
                f"{system}.{item_id} is {item.type}",
            )

    def check_command(self, i: CommandInstruction) -> None:
        sysrep = self.system(i, i.system)
        if sysrep is None:
            return
        command = sysrep.command(i.command)
        if command is None:
            self.fail(
                i.at("name"),
                f"unknown command {i.command!r} in {i.system} (commands: {', '.join(c.id for c in sysrep.commands)})",
            )
            return
        expected = [a.name for a in command.args]
        for binding in i.args:
            argument = command.arg(binding.name)
            if argument is None:
                self.fail(
                    binding.where, f"{i.command}: unknown argument {binding.name!r} (expected: {', '.join(expected)})"
                )
                continue
            typed = self.check_value(binding, argument.type, f"{i.command}: argument {binding.name!r}", argument.check)
            if typed is not _UNTYPED:
                self.session.literals[binding] = typed
        missing = [name for name in expected if name not in {b.name for b in i.args}]
        if missing:
            self.fail(
                i.where,
                f"{i.command}: missing argument{'s' if len(missing) > 1 else ''} {', '.join(map(repr, missing))} "
                f"({len(i.args)} given, {len(expected)} expected: {', '.join(expected)})",
            )

    def check_value(self, binding: ArgumentBinding, type_name: str, what: str, check: Callable[[str], Any]) -> Any:
        """The typed value of an argument written as text; _UNTYPED when it has references or is wrong."""
        whole = binding.value.whole_reference
        if whole is not None:
            var = self.variables.get(whole.name)
            var_type, source = (var.type, var.source) if var is not None else (None, "")
            if var is not None and var.source == "call" and whole.field is not None:
                callee, outputs = self.call_outputs.get(whole.name, ("", {}))
                var_type, source = outputs.get(whole.field), f"output of {callee}"
            if var_type is not None and var_type != type_name and type_name != "string":
                self.fail(binding.where, f"{what}: expected {type_name}, but {whole} is a {var_type} {source}")
            return _UNTYPED
        if binding.value.references:
            if type_name != "string":
                self.fail(binding.where, f"{what}: expected {type_name}; text mixed with ${{...}} is a string")
            return _UNTYPED
        if not str(binding.value).strip():
            self.fail(binding.where, f"{what} is empty: write its value (every argument is required)")
            return _UNTYPED
        try:
            return check(str(binding.value))
        except ValueError as exc:
            self.fail(binding.where, f"{what}: {str(exc).split(': ', 1)[-1]}")
            return _UNTYPED

    def check_condition(self, i: _Placed, subject: Subject, condition: Condition) -> None:
        type_name: str | None = None
        if subject.source == "telemetry":
            item = self.item(i, subject.system, subject.name)
            if item is None:
                return
            type_name = item.type
        elif subject.source == "input":
            var = self.variables.get(subject.name)
            type_name = var.type if var is not None and var.source != "result" else None
            if var is not None and var.source == "result":
                self.fail(i.at("input"), f'{subject.name!r} is a command result; write result="{subject.name}.success"')
        elif subject.source == "result":
            var = self.variables.get(subject.name)
            if var is not None and var.source not in ("result", "call"):
                self.fail(
                    i.at("result"),
                    f'{subject.name!r} is a {var.source}, not a command result; write input="{subject.name}"',
                )
            if var is not None and var.source == "call":
                type_name = self.call_outputs.get(subject.name, ("", {}))[1].get(subject.field or "")
            else:
                type_name = "boolean" if subject.field == "success" else None
        if type_name is None:
            return
        for attribute, text in (
            ("equals", condition.equals),
            ("not-equals", condition.not_equals),
            ("min", condition.minimum),
            ("max", condition.maximum),
        ):
            if text is None:
                continue
            if attribute in ("min", "max") and type_name not in ("integer", "real"):
                self.fail(i.at(attribute), f"{attribute} compares numbers; {subject.describe()} is {type_name}")
                continue
            try:
                check_value(attribute, type_name, text)
            except ValueError as exc:
                self.fail(i.at(attribute), f"{subject.describe()} is {type_name}: {exc}")
        if condition.tolerance is not None and type_name not in ("integer", "real"):
            self.fail(i.at("tolerance"), f"tolerance applies to numbers; {subject.describe()} is {type_name}")

    def check_call(self, i: CallInstruction) -> None:
        path = Path(i.resolved_path)
        try:
            found = path.is_file()
        except OSError as exc:  # a name no file system accepts (too long, ...)
            self.fail(i.at("procedure"), f"sub-procedure {i.procedure!r} cannot be a file: {exc.strerror}")
            return
        if not found:
            self.fail(i.at("procedure"), f"sub-procedure file not found: {i.procedure} (looked at {path})")
            return
        if str(path) in self.seen:
            self.fail(i.at("procedure"), f"sub-procedure {i.procedure} calls itself (directly or through others)")
            return
        callee, problems = self.session.lint(path, self.seen)
        if callee is None or problems:
            self.problems.extend(problems)
            self.fail(i.at("procedure"), f"sub-procedure {i.procedure} has {len(problems)} error(s)")
            return
        declared = {inp.name: inp for inp in callee.inputs}
        for binding in i.args:
            if binding.name not in declared:
                self.fail(
                    binding.where,
                    f"{callee.id}: unknown input {binding.name!r} (declared inputs: {', '.join(declared) or 'none'})",
                )
                continue
            inp = declared[binding.name]
            self.check_value(
                binding,
                inp.type,
                f"{callee.id}: input {binding.name!r}",
                functools.partial(check_value, inp.name, inp.type),
            )
        missing = [name for name in declared if name not in {b.name for b in i.args}]
        if missing:
            self.fail(
                i.where, f"{callee.id}: missing input{'s' if len(missing) > 1 else ''} {', '.join(map(repr, missing))}"
            )
        for monitor in (m for step in callee.steps for m in step.monitors):  # never silently unwatched
            why = f"{callee.id} is called ({i.where}): a called procedure's monitors are not watched"
            self.fail(monitor.where, f"{why}; put this monitor in the calling step")
        if i.result:
            self.call_outputs[i.result] = (callee.id, {o.name: o.type for o in callee.outputs})
            if not callee.outputs:
                self.fail(i.at("result"), f"{callee.id} declares no output: result={i.result!r} would hold nothing")

    # ---- control flow -----------------------------------------------------------------------
    def first_of(self, ref: str | None) -> int | None:
        step = self.proc.step(ref) if ref is not None else None
        return self.index[step.instructions[0].number] if step is not None and step.instructions else None

    def control_flow(self) -> list[list[int]]:
        """Successors of each instruction (index into the flat list); len(flat) means the end."""
        end = len(self.flat)
        successors: list[list[int]] = []
        for n, i in enumerate(self.flat):
            following = self.proc.following(n)
            targets: list[int | None]
            if isinstance(i, GoToInstruction):
                targets = [self.first_of(i.step)]
            elif isinstance(i, BranchInstruction):
                targets = [self.first_of(i.goto), self.first_of(i.else_goto) if i.else_goto else following]
            elif isinstance(i, (CommandInstruction, VerifyInstruction, WaitInstruction)) and i.on_failure:
                targets = [following, self.first_of(i.on_failure)]
            else:
                targets = [following]
            targets += self.monitor_targets(i)
            successors.append(sorted({t if t is not None else end for t in targets if t is not None}))
        return successors

    def monitor_targets(self, i: Instruction) -> list[int | None]:
        """Where a monitor active at ``i`` may send the run: any moment of its step (or after, for one
        of the whole procedure) may go to its contingency."""
        step = int(i.number.split(".")[0])
        return [
            self.first_of(m.goto)
            for s in self.proc.steps
            for m in s.monitors
            if m.on_violation == "goto" and (m.step == step or (m.scope == "procedure" and m.step <= step))
        ]

    def reached_from(self, successors: list[list[int]], start: int) -> set[int]:
        reached: set[int] = set()
        todo = [start] if self.flat else []
        while todo:
            n = todo.pop()
            if n in reached or n >= len(self.flat):
                continue
            reached.add(n)
            todo.extend(successors[n])
        return reached

    def reachability(self, successors: list[list[int]]) -> set[int]:
        reached = self.reached_from(successors, 0)
        for step in self.proc.steps:
            numbers = [self.index[i.number] for i in step.instructions]
            if numbers and not any(n in reached for n in numbers):
                self.fail(
                    step.where,
                    f"step {step.number} ({step.title!r}) is unreachable: no go-to or preceding step leads to it",
                )
                continue
            for n in numbers:
                if n not in reached:
                    self.fail(
                        self.flat[n].where,
                        f"instruction {self.flat[n].number} is unreachable "
                        "(the instruction before it always goes elsewhere)",
                    )
        return reached

    def defined_before(
        self, successors: list[list[int]], reachable: set[int], start: int, entry: frozenset[str]
    ) -> dict[int, frozenset[str]]:
        """The names bound on every path from ``start`` (where ``entry`` is bound) to each reachable instruction."""
        everything = frozenset(self.variables)
        defined_in: dict[int, frozenset[str]] = {n: everything for n in reachable}
        if start in reachable:
            defined_in[start] = entry
        predecessors: dict[int, list[int]] = {n: [] for n in reachable}
        for n in reachable:
            for s in successors[n]:
                if s in predecessors:
                    predecessors[s].append(n)
        changed = True
        while changed:
            changed = False
            for n in sorted(reachable):
                sets = [self.defined_out(p, defined_in[p]) for p in predecessors[n]]
                if n == start:
                    sets.append(entry)
                new = frozenset.intersection(*sets) if sets else entry
                if new != defined_in[n]:
                    defined_in[n] = new
                    changed = True
        return defined_in

    def check_variables(self, successors: list[list[int]], reachable: set[int]) -> None:
        """Every ``${...}`` and condition input must be defined on every path that reaches it."""
        entry = frozenset(inp.name for inp in self.proc.inputs)
        defined_in = self.defined_before(successors, reachable, 0, entry)
        self.check_outputs_set(successors, reachable, defined_in)
        for n in sorted(reachable):
            for ref, where in self.uses(self.flat[n]):
                if ref.name not in self.variables:
                    self.fail(
                        where,
                        f"unbound variable {ref.name!r}: no input, record, output, command result or call result "
                        "of that name",
                    )
                elif ref.name not in defined_in[n]:
                    self.fail(
                        where,
                        f"unbound variable {ref.name!r}: not recorded or returned before "
                        f"{self.flat[n].number} on every path",
                    )
                else:
                    self.check_reference(ref, where)

    def check_reference(self, ref: Reference, where: Location) -> None:
        """A bound reference names a value the way its variable holds it (a call's outputs by name)."""
        source = self.variables[ref.name].source
        if source == "call":
            callee, outputs = self.call_outputs.get(ref.name, ("", {}))
            if ref.field is None:
                listed = ", ".join(outputs) or "none"
                self.fail(where, f"{ref}: {ref.name!r} holds {callee}'s outputs; name one ({listed})")
            elif callee and ref.field not in outputs:
                listed = ", ".join(outputs) or "none"
                self.fail(where, f"{ref}: {callee} declares no output {ref.field!r} (its outputs: {listed})")
        elif ref.field is not None and source != "result":
            self.fail(where, f"{ref}: {ref.name!r} is a {source}, write ${{{ref.name}}}")
        elif ref.field is None and source == "result":
            self.fail(where, f"{ref}: {ref.name!r} is a command result; name a value, e.g. ${{{ref.name}.success}}")

    def check_outputs_set(
        self, successors: list[list[int]], reachable: set[int], defined_in: dict[int, frozenset[str]]
    ) -> None:
        """Every declared output is set on every path that ends the procedure (its caller reads them)."""
        end = len(self.flat)
        ends = [n for n in sorted(reachable) if end in successors[n]]
        if not ends or not self.proc.outputs:
            return
        for output in self.proc.outputs:
            unset = [n for n in ends if output.name not in self.defined_out(n, defined_in[n])]
            if unset:
                self.fail(
                    output.where,
                    f"output {output.name!r} is not set on every path that ends {self.proc.id}: not set when it "
                    f"ends after {', '.join(self.flat[n].number for n in unset)} "
                    f'(add <set name="{output.name}">...</set> on that path)',
                )

    def defined_out(self, n: int, defined: frozenset[str]) -> frozenset[str]:
        i = self.flat[n]
        if isinstance(i, RecordInstruction):
            return defined | {i.name}
        if isinstance(i, (CommandInstruction, CallInstruction)) and i.result:
            return defined | {i.result}
        if isinstance(i, SetInstruction):
            return defined | {i.name}
        return defined

    @staticmethod
    def uses(i: Instruction) -> list[tuple[Reference, Location]]:
        found: list[tuple[Reference, Location]] = []
        if isinstance(i, (CommandInstruction, CallInstruction)):
            found += [(ref, b.where) for b in i.args for ref in b.value.references]
        if isinstance(i, SetInstruction):
            found += [(ref, i.at("value")) for ref in i.value.references]
        if isinstance(i, BranchInstruction) and i.subject.source in ("input", "result"):
            ref = Reference(i.subject.name, i.subject.field if i.subject.source == "result" else None)
            found.append((ref, i.at(i.subject.source)))
        found += [(ref, i.at("text")) for ref in Template.parse(i.text).references]  # the sentence shows them
        return found
