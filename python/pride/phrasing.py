"""How a procedure reads to an operator: sentences, labelled values and plain audit lines, not code.

An instruction reads as the author's ``<text>`` when there is one. Otherwise its sentence is made
from the SysRep's labels:

- command: the command's label; the argument the label names (``trajectory`` for "Plan
  Trajectory", ``affordance_template`` for "Add Affordance Template") follows it in quotes; the
  first other argument follows "for"; the rest come in brackets as "name: value", with x/y/z
  and roll/pitch/yaw grouped as position and orientation (``Plan Trajectory "grasp_and_pull"
  for cdra_filter:${cdra_at.id}``);
- verify / wait: "Verify <telemetry label> is <condition>", "Wait until …", "Wait 2 s";
- branch / go-to / call: "If …, go to step 3 (title)", "Go to step 2 (title)", "Run <title> with …";
- record / manual: their text, which the schema requires.

A sentence is a :class:`~pride.model.Template`: ``${...}`` stay references, which a view fills in
once the run knows their values. The raw command (``system.command(arg=value, …)``) is kept for
whoever wants to see exactly what is sent. Values are shown rounded (``0.35``, not
``0.3500000000000001``), with units where the SysRep gives them, and never as Python reprs.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from pride.events import Event, EventKind
from pride.model import (
    BranchInstruction,
    CallInstruction,
    CommandInstruction,
    Condition,
    GoToInstruction,
    Instruction,
    Procedure,
    Reference,
    Subject,
    Template,
    VerifyInstruction,
    WaitInstruction,
)
from pride.sysrep import SysRep

__all__ = [
    "describe_event",
    "fill_text",
    "format_value",
    "humanize",
    "labelled_values",
    "phrase",
    "raw_form",
    "started_text",
    "template_json",
]

_POSITION = ("x", "y", "z")
_ORIENTATION = ("roll", "pitch", "yaw")
#: Decimals a real is rounded to when shown (a millimetre, a milliradian).
_DECIMALS = 3


def format_value(value: Any, units: str | None = None) -> str:
    """A value as an operator reads it: rounded reals, true/false, lists in brackets, no quotes."""
    if isinstance(value, bool):
        text = "true" if value else "false"
    elif isinstance(value, float):
        text = _real(value)
    elif isinstance(value, (list, tuple)):
        text = "(" + ", ".join(format_value(v) for v in value) + ")"
    elif isinstance(value, dict):
        text = ", ".join(f"{humanize(str(k))} {format_value(v)}" for k, v in value.items())
    elif value is None:
        text = "—"
    else:
        text = str(value)
    return f"{text} {units}" if units and not isinstance(value, (bool, dict)) and value is not None else text


def _real(value: float) -> str:
    if value != value or value in (float("inf"), float("-inf")):
        return str(value)
    if value != 0 and abs(value) < 10**-_DECIMALS:
        return f"{value:.2e}"
    text = f"{value:.{_DECIMALS}f}".rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def humanize(identifier: str) -> str:
    """``end_pose`` → ``end pose``: an identifier as words."""
    return identifier.replace("_", " ").strip()


# ---- instruction sentences -------------------------------------------------------------------
def phrase(
    instruction: Instruction,
    sysreps: Mapping[str, SysRep],
    procedure: Procedure | None = None,
    *,
    callee: Procedure | None = None,
) -> Template:
    """The instruction as a sentence (with ``${...}`` left as references)."""
    if instruction.text:
        return Template.parse(instruction.text)
    if isinstance(instruction, CommandInstruction):
        return _command(instruction, sysreps)
    if isinstance(instruction, VerifyInstruction):
        condition = _condition(instruction.condition, instruction.subject, sysreps)
        return Template((f"Verify {_subject(instruction.subject, sysreps)} {condition}",))
    if isinstance(instruction, WaitInstruction):
        if instruction.subject is not None and instruction.condition is not None:
            return Template(
                (
                    f"Wait until {_subject(instruction.subject, sysreps)} "
                    f"{_condition(instruction.condition, instruction.subject, sysreps)}",
                )
            )
        return Template((f"Wait {format_value(instruction.seconds)} s",))
    if isinstance(instruction, BranchInstruction):
        otherwise = f", otherwise to {_step(instruction.else_goto, procedure)}" if instruction.else_goto else ""
        condition = _condition(instruction.condition, instruction.subject, sysreps)
        return Template(
            (
                f"If {_subject(instruction.subject, sysreps)} {condition}, "
                f"go to {_step(instruction.goto, procedure)}{otherwise}",
            )
        )
    if isinstance(instruction, GoToInstruction):
        return Template((f"Go to {_step(instruction.step, procedure)}",))
    if isinstance(instruction, CallInstruction):
        name = f'"{callee.title}"' if callee is not None else instruction.procedure
        parts: list[str | Reference] = [f"Run {name}"]
        if instruction.args:
            parts.append(" with ")
            parts += _join([_pair(a.name, a.value) for a in instruction.args])
        return _template(parts)
    return Template((instruction.describe(),))


def _command(instruction: CommandInstruction, sysreps: Mapping[str, SysRep]) -> Template:
    sysrep = sysreps.get(instruction.system)
    command = sysrep.command(instruction.command) if sysrep is not None else None
    label = command.label if command is not None else humanize(instruction.command).capitalize()
    args = {a.name: a.value for a in instruction.args}
    named = _named_argument(label, list(args))
    first = next(iter(args), None)  # by convention the command's target (Fig. 1: affordance_template)
    parts: list[str | Reference] = [label]
    if named is not None:
        parts += [' "', *args.pop(named).parts, '"']
    if first is not None and first != named:
        parts += [" for ", *args.pop(first).parts]
    rest: list[list[str | Reference]] = []
    for group, word in ((_POSITION, "position"), (_ORIENTATION, "orientation")):
        if all(name in args for name in group):
            values = [args.pop(name) for name in group]
            units = _units(command, group[0])
            rest.append([f"{word} (", *_join([list(v.parts) for v in values]), ")" + (f" {units}" if units else "")])
    rest[:0] = [_pair(name, value, _units(command, name)) for name, value in args.items()]
    if rest:
        parts += [" (", *_join(rest), ")"]
    return _template(parts)


def _named_argument(label: str, names: list[str]) -> str | None:
    """The argument the label names ("Plan Trajectory" → trajectory), longest run of its words first."""
    words = [w.lower() for w in label.split()[1:]]
    for length in range(len(words), 0, -1):
        for start in range(len(words) - length + 1):
            candidate = "_".join(words[start : start + length])
            if candidate in names:
                return candidate
    return None


def _units(command: Any, name: str) -> str | None:
    argument = command.arg(name) if command is not None else None
    return argument.units if argument is not None else None


def _pair(name: str, value: Template, units: str | None = None) -> list[str | Reference]:
    return [f"{humanize(name)}: ", *value.parts, *([f" {units}"] if units else [])]


def _join(items: list[list[str | Reference]]) -> list[str | Reference]:
    joined: list[str | Reference] = []
    for n, item in enumerate(items):
        if n:
            joined.append(", ")
        joined += item
    return joined


def _template(parts: list[str | Reference]) -> Template:
    """Adjacent texts merged, so a sentence is as few parts as it can be."""
    merged: list[str | Reference] = []
    for part in parts:
        if isinstance(part, str) and merged and isinstance(merged[-1], str):
            merged[-1] += part
        elif part != "":
            merged.append(part)
    return Template(tuple(merged) or ("",))


def _telemetry(subject: Subject, sysreps: Mapping[str, SysRep]) -> Any:
    sysrep = sysreps.get(subject.system or "")
    return sysrep.telemetry_item(subject.name) if sysrep is not None else None


def _subject(subject: Subject, sysreps: Mapping[str, SysRep]) -> str:
    if subject.source == "telemetry":
        item = _telemetry(subject, sysreps)
        return item.label if item is not None else humanize(subject.name)
    if subject.source == "result":
        return f"{humanize(subject.name)} {humanize(subject.field or 'success')}"
    return f"the recorded {humanize(subject.name)}"


_CONDITION_WORDS = (("equals", "is"), ("not_equals", "is not"), ("minimum", "is at least"), ("maximum", "is at most"))


def _condition(condition: Condition, subject: Subject, sysreps: Mapping[str, SysRep]) -> str:
    """The condition in words ("is at least 2 m"); Condition.describe() has it in symbols."""
    item = _telemetry(subject, sysreps) if subject.source == "telemetry" else None
    units = f" {item.units}" if item is not None and item.units else ""
    tolerance = f" ± {format_value(condition.tolerance)}" if condition.tolerance is not None else ""
    return " and ".join(
        f"{words} {getattr(condition, name)}{tolerance if name == 'equals' else ''}{units}"
        for name, words in _CONDITION_WORDS
        if getattr(condition, name) is not None
    )


def _step(reference: str | None, procedure: Procedure | None) -> str:
    step = procedure.step(reference) if procedure is not None and reference is not None else None
    return f"step {step.number} ({step.title})" if step is not None else f"step {reference}"


def raw_form(instruction: Instruction) -> str:
    """Exactly what the instruction does, in the procedure's own terms (the "raw command" view)."""
    if isinstance(instruction, CommandInstruction):
        args = ", ".join(f"{a.name}={a.value}" for a in instruction.args)
        return f"{instruction.system}.{instruction.command}({args})"
    if (
        isinstance(instruction, (VerifyInstruction, WaitInstruction))
        and instruction.subject is not None
        and instruction.condition
    ):
        subject, condition = instruction.subject.describe(), instruction.condition.describe()
        return f"{instruction.kind.value} {subject} {condition} (timeout {instruction.timeout:g} s)"
    if isinstance(instruction, BranchInstruction):
        otherwise = f" else {instruction.else_goto}" if instruction.else_goto else ""
        return (
            f"if {instruction.subject.describe()} {instruction.condition.describe()} goto {instruction.goto}{otherwise}"
        )
    if isinstance(instruction, CallInstruction):
        args = ", ".join(f"{a.name}={a.value}" for a in instruction.args)
        return f"call {instruction.procedure}({args})"
    if isinstance(instruction, GoToInstruction):
        return f"goto {instruction.step}"
    if isinstance(instruction, WaitInstruction):
        return f"wait {instruction.seconds:g} s"
    return f"{instruction.kind.value}: {instruction.text}"


def template_json(template: Template) -> list[dict[str, str]]:
    """A sentence for the page: texts and references (``{"ref": "cdra_at.id"}``) to fill in."""
    return [
        {"text": p} if isinstance(p, str) else {"ref": f"{p.name}.{p.field}" if p.field else p.name}
        for p in template.parts
    ]


# ---- values and audit records ----------------------------------------------------------------
def labelled_values(values: Mapping[str, Any], sysrep: SysRep | None = None) -> list[tuple[str, str]]:
    """A command's result values as (label, text): the SysRep's telemetry label and units where a
    value shares a telemetry item's id (``plan_status`` → "Plan Status"), else the key as words."""
    lines = []
    for key, value in values.items():
        item = sysrep.telemetry_item(key) if sysrep is not None else None
        label = item.label if item is not None else humanize(key)
        lines.append((label, format_value(value, item.units if item is not None else None)))
    return lines


def _values(values: Any) -> str:
    if not isinstance(values, Mapping) or not values:
        return ""
    return " · " + ", ".join(f"{label} {text}" for label, text in labelled_values(values))


#: How a command's outcome reads; an unknown one is neither a success nor a failure.
_OUTCOME_WORDS = {"succeeded": "succeeded", "failed": "FAILED", "unknown": "OUTCOME UNKNOWN", "halted": "HALTED"}


def _reason(data: dict[str, Any]) -> str:
    return f": {data['reason']}" if data.get("reason") else ""


def fill_text(text: str, env: dict[str, Any]) -> str:
    """An instruction's sentence as written, with the values ``env`` holds filled in (written as
    :func:`format_value` writes them); one the run does not know yet stays ``${...}``."""
    return Template.parse(text).fill(env, format_value)


def started_text(event: Event) -> str:
    """The sentence of an instruction-started event as people read it: with the values the run knew
    when it began filled in (``text_filled``), else, in a log recorded before events carried that,
    the author's text with its ``${...}``."""
    data = event.data or {}
    filled = data.get("text_filled")
    return str(filled) if filled is not None else str(data.get("text", ""))


def describe_event(event: Event) -> str:
    """One line saying what an audit record was, in words (the web view's log and the report)."""
    d = event.data
    kind = event.kind
    if kind is EventKind.RUN_STARTED:
        return f"started {d.get('procedure')} v{d.get('version')} in {d.get('mode')} mode"
    if kind is EventKind.RUN_RESUMED:
        return f"resumed in {d.get('mode')} mode" + (" (a command was in flight)" if d.get("in_flight") else "")
    if kind is EventKind.COMMAND_SENT:
        args = ", ".join(f"{k}={format_value(v)}" for k, v in (d.get("args") or {}).items())
        return f"sent {d.get('system')}.{d.get('command')}({args})" + (" [hazardous]" if d.get("hazardous") else "")
    if kind is EventKind.COMMAND_RESULT:
        message = f": {d['message']}" if d.get("message") else ""
        outcome = _OUTCOME_WORDS.get(str(d.get("outcome")), "succeeded" if d.get("success") else "FAILED")
        return f"{outcome}{message}{_values(d.get('values'))}"
    if kind is EventKind.TELEMETRY_SEEN:
        verdict = "" if "ok" not in d else (" ✓" if d["ok"] else " ✗")
        stale = " (stale)" if d.get("stale") else ""
        return f"saw {d.get('system')}.{d.get('item')} = {format_value(d.get('value'))}{stale}{verdict}"
    if kind is EventKind.OPERATOR_INPUT:
        return f"recorded {d.get('name')} = {format_value(d.get('value'))}"
    if kind is EventKind.INSTRUCTION_FAILED:
        return f"failed: {d.get('reason', '')}" + (f" → step {d['branch']}" if d.get("branch") else "")
    if kind is EventKind.INSTRUCTION_SKIPPED:
        return f"skipped: {d.get('reason', '')}"
    if kind is EventKind.INSTRUCTION_COMPLETED:
        return "completed" + (f" → step {d['went_to']}" if d.get("went_to") else "")
    if kind is EventKind.INSTRUCTION_STARTED:
        return f"started: {started_text(event)}"
    if kind is EventKind.AWAITING_OPERATOR:
        return f"waiting for an operator: {d.get('reason', '')}"
    if kind is EventKind.MODE_CHANGED:
        return f"mode → {d.get('mode')}"
    if kind is EventKind.RUN_STOPPED:
        return f"stopped: {d.get('reason', '')}"
    if kind is EventKind.RETRY:
        return f"retry after: {d.get('after', '')}"
    if kind is EventKind.CALL_ENTERED:
        inputs = ", ".join(f"{k}={format_value(v)}" for k, v in (d.get("inputs") or {}).items())
        return f"entered {d.get('procedure')} with {inputs or 'no inputs'}"
    if kind is EventKind.CONFIRMATION:
        return f"confirmed the hazardous command: {d.get('command', '')}"
    if kind is EventKind.HALT:
        told = (d.get("cancel") or {}).get("message")
        return f"HALT{_reason(d)}" + (f"; the system: {told}" if told else "")
    if kind is EventKind.INSTRUCTION_HALTED:
        return f"halted before it finished{_reason(d)}"
    if kind is EventKind.OUTCOME_RESOLVED:
        return f"recorded the unknown outcome as {d.get('outcome')}{_reason(d)}"
    if kind is EventKind.RECORD_CORRECTED:
        return f"corrected {d.get('name')}: {format_value(d.get('old'))} → {format_value(d.get('value'))}{_reason(d)}"
    if kind is EventKind.STEPPED_BACK:
        return f"went back to {d.get('next')}{_reason(d)}"
    if kind is EventKind.LINK_LOST:
        n = d.get("in_flight", 0)
        what = "no news from the habitat" if d.get("quiet") else "link lost"  # quiet: held, not yet given up
        return f"{what} since {str(d.get('since', ''))[11:19]} UTC, {n} command{'' if n == 1 else 's'} in flight"
    if kind is EventKind.LINK_RESTORED:
        return f"link restored after {d.get('seconds')} s"
    if kind is EventKind.CONTROL_TAKEN:
        return f"took control of {d.get('robot')} from run {d.get('from_run')} ({d.get('from_user')}){_reason(d)}"
    if kind is EventKind.CONTROL_LOST:
        return f"control of {d.get('robot')} taken over by {d.get('by_user')} (run {d.get('by_run')}){_reason(d)}"
    return str(kind.value).replace("_", " ")
