"""How a procedure and its run read to an operator: sentences, rounded values with units and plain
audit lines, not code. One module phrases all of it, so the procedure view, the audit panel, the
after-action report and the runner's terminal say the same thing the same way (a run's events in
words: :mod:`pride.event_words`).

An instruction reads as the author's ``<text>`` when there is one. Otherwise its sentence is made
from the SysRep's labels (an id as title-cased words where no SysRep is at hand, as Fig. 1 writes
its labels):

- command: the command's label; the argument the label names (``trajectory`` for "Plan
  Trajectory", ``affordance_template`` for "Add Affordance Template") follows it in quotes; the
  first other argument follows "for"; the rest come in brackets as "name: value", with x/y/z
  and roll/pitch/yaw grouped as position and orientation (``Plan Trajectory "grasp_and_pull"
  for cdra_filter:${cdra_at.id}``);
- verify / wait: "Verify <telemetry label> is <condition>", "Wait until …", "Wait 2 s";
- branch / go-to / call: "If …, go to step 3 (title)", "Go to step 2 (title)", "Run <title> with …";
- record / manual: their text, which the schema requires.

A sentence is a :class:`~procedure_language.model.Template`: ``${...}`` stay references, which a view fills in
once the run knows their values. Filled in here (:func:`fill_text`), a value the run does not know
yet reads "‹cdra at id: not known yet›": people never read ``${...}``.

A command that was sent reads as its instruction's sentence, with the values sent
(:func:`command_text`): ``Set Display Object Pose "part" for relocate_part:0 (id: 0, frame:
shelf/slot_a, position 0 mm, orientation 0°)``. The call itself, every value exactly as sent
(``affordance_templates.set_display_object_pose(affordance_template=relocate_part:0, …)``), is
for whoever turns on the raw-commands switch: the web view's "raw commands" box, ``--raw`` of
``caretaker run`` and ``caretaker report`` (:attr:`Wording.raw`).

Values are rounded to what an operator can use, never shown as Python reprs:

- lengths (SysRep units ``m``; without units, ``x``/``y``/``z`` and a pose's position, metres by
  the ROS convention REP 103, as Fig. 1's poses are) in millimetres, no decimals, one below
  10 mm (``150 mm``, ``4.5 mm``): registrations and reaches are checked to the millimetre, and
  planner noise (0.14999985 m) disappears;
- angles (SysRep units ``rad``; without units, ``roll``/``pitch``/``yaw`` and a pose's
  orientation, radians by REP 103) in degrees, one decimal (``90°``, ``12.5°``): people picture
  90°, not 1.5708 rad, and a tenth of a degree is finer than any check an operator makes;
- a value already in millimetres or degrees (SysRep units ``mm`` or ``deg``, or a name ending in
  ``_mm`` or ``_deg``, as perception's ``offset_mm``) rounded as above: ``0.7``, not ``0.6552``;
- a result's quaternion (``qx``, ``qy``, ``qz``, ``qw``) is not shown beside the roll, pitch and
  yaw that say the same orientation in degrees;
- joint values (a list whose name says ``joint``) in degrees like every other angle;
- a pose (six numbers whose name ends in ``pose``: x, y, z, roll, pitch, yaw) as ``position
  (150, 450, 300) mm, orientation (0, 90, 90)°``, "in <frame>" when a ``<name>_frame`` value
  names its frame; a group that is all zero as ``position 0 mm``;
- other reals to 4 significant digits, at most 4 decimals (``0.3333``, ``21.5``, ``1235``),
  below 0.0001 as ``3.4e-10``, with the SysRep's units; integers and strings as they are;
  booleans true/false; nothing as "—".
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from procedure_language.model import (
    ArgumentBinding,
    BranchInstruction,
    CallInstruction,
    CommandInstruction,
    Condition,
    GoToInstruction,
    Instruction,
    Procedure,
    Reference,
    SetInstruction,
    Subject,
    Template,
    VerifyInstruction,
    WaitInstruction,
    lookup,
)
from procedure_language.sysrep import Argument, Command, SysRep

__all__ = [
    "Wording",
    "command_definition",
    "command_text",
    "condition_words",
    "fill_text",
    "filled_sentence",
    "format_value",
    "humanize",
    "in_order",
    "labelled_values",
    "phrase",
    "raw_call",
    "raw_form",
    "record_refusal",
    "telemetry_item",
    "telemetry_label",
    "template_json",
]

_POSITION = ("x", "y", "z")
_ORIENTATION = ("roll", "pitch", "yaw")
_LENGTH, _ANGLE = "length", "angle"
#: Values already in millimetres or degrees: rounded as lengths and angles, not converted.
_MILLIMETRES, _DEGREES = "millimetres", "degrees"
#: What a value measures, by its SysRep units (others keep their units and are plain reals).
_KIND_OF_UNITS = {"m": _LENGTH, "rad": _ANGLE, "mm": _MILLIMETRES, "deg": _DEGREES}
#: ... and by the end of its name where it has no units (the name then says the unit).
_KIND_OF_SUFFIX = {"_mm": _MILLIMETRES, "_deg": _DEGREES}
#: A quaternion's components, left out of a result that says its orientation as roll, pitch and yaw.
_QUATERNION = ("qx", "qy", "qz", "qw")
#: The units a length or an angle is written in where it is not a number yet (a ``${...}``):
#: the SI units the run sends, so the value filled in later reads right.
_SI = {_LENGTH: "m", _ANGLE: "rad"}
#: Significant digits (and at most as many decimals) of a real that is no length or angle.
_SIGNIFICANT = 4


@dataclass(frozen=True)
class Wording:
    """How a run's records read: the SysReps whose labels and units they use (ids as words when
    one is missing) and whether a sent command also shows the call as sent (the raw switch)."""

    sysreps: Mapping[str, SysRep] = field(default_factory=dict)
    raw: bool = False


# ---- values ----------------------------------------------------------------------------------
def format_value(value: Any, units: str | None = None, *, name: str = "") -> str:
    """A value as an operator reads it (the rules are in the module docstring): ``units`` are the
    SysRep's, ``name`` the value's id, which says what it measures where no units do."""
    kind = _kind(name, units)
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int) and kind is None:
        return f"{value}{_suffix(None, units)}"
    if isinstance(value, (int, float)):
        return _number(float(value), kind) + _suffix(kind, units)
    if isinstance(value, (list, tuple)):
        numbers = [float(v) for v in value if isinstance(v, (int, float)) and not isinstance(v, bool)]
        if len(numbers) != len(value):
            return "(" + ", ".join(format_value(v) for v in value) + ")" + _suffix(None, units)
        if len(numbers) == 6 and name.endswith("pose"):
            return f"{_group('position', numbers[:3], _LENGTH)}, {_group('orientation', numbers[3:], _ANGLE)}"
        kind = kind or (_ANGLE if "joint" in name else None)
        return "(" + ", ".join(_number(v, kind) for v in numbers) + ")" + _suffix(kind, units)
    if isinstance(value, Mapping):
        return ", ".join(f"{humanize(str(k))} {format_value(v, name=str(k))}" for k, v in value.items())
    if value is None:
        return "—"
    return f"{value}{_suffix(None, units)}"


def _kind(name: str, units: str | None) -> str | None:
    """Whether a value is a length or an angle: by its units, else by its name (REP 103)."""
    if units:
        return _KIND_OF_UNITS.get(units)
    if name in _POSITION:
        return _LENGTH
    if name in _ORIENTATION:
        return _ANGLE
    return next((kind for suffix, kind in _KIND_OF_SUFFIX.items() if name.endswith(suffix)), None)


def _suffix(kind: str | None, units: str | None) -> str:
    if kind == _LENGTH:
        return " mm"
    if kind == _ANGLE or (kind == _DEGREES and units):
        return "°"
    return f" {units}" if units else ""


def _number(value: float, kind: str | None) -> str:
    """A number without its units: metres as millimetres, radians as degrees, other reals rounded."""
    if kind in (_LENGTH, _MILLIMETRES):
        millimetres = value * 1000 if kind == _LENGTH else value
        return _fixed(millimetres, 1 if abs(millimetres) < 10 else 0)
    if kind in (_ANGLE, _DEGREES):
        return _fixed(math.degrees(value) if kind == _ANGLE else value, 1)
    if not math.isfinite(value) or value == 0:
        return _fixed(value, 0)
    if abs(value) < 10**-_SIGNIFICANT:
        return f"{value:.1e}"
    whole_digits = math.floor(math.log10(abs(value))) + 1
    return _fixed(value, min(_SIGNIFICANT, max(0, _SIGNIFICANT - whole_digits)))


def _fixed(value: float, decimals: int) -> str:
    """``value`` to ``decimals`` places without trailing zeros, and never "-0"."""
    text = f"{value:.{decimals}f}"
    if "." in text:
        text = text.rstrip("0").rstrip(".")
    return "0" if text == "-0" else text


def _group(word: str, numbers: Sequence[float], kind: str | None, units: str | None = None) -> str:
    """x/y/z or roll/pitch/yaw as one value: ``position (350, 0, 1000) mm``, ``orientation 0°``."""
    texts = [_number(v, kind) for v in numbers]
    shown = "0" if all(t == "0" for t in texts) else f"({', '.join(texts)})"
    return f"{word} {shown}{_suffix(kind, units)}"


def humanize(identifier: str) -> str:
    """``end_pose`` → ``end pose``: an identifier as words."""
    return identifier.replace("_", " ").strip()


def _titled(identifier: str) -> str:
    """``unlock_filter`` → ``Unlock Filter``: a label where no SysRep gives one, written as Fig. 1's are."""
    return humanize(identifier).title()


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
            parts += _join([[f"{humanize(a.name)}: ", *a.value.parts] for a in instruction.args])
        return _template(parts)
    if isinstance(instruction, SetInstruction):
        return _template([f"Set {humanize(instruction.name)} to ", *instruction.value.parts])
    return Template((instruction.describe(),))


def filled_sentence(
    instruction: Instruction, sysreps: Mapping[str, SysRep], procedure: Procedure, env: dict[str, Any]
) -> str:
    """The instruction's sentence with the values the run knows now (``env``) filled in: what a
    hold, a confirmation or a started instruction says."""
    return fill_text(str(phrase(instruction, sysreps, procedure)), env)


@dataclass(frozen=True)
class _Argument:
    """A command argument as its sentence shows it: as written (with references) or as sent,
    and its value as a number where that is known now (a length or an angle is shown converted)."""

    name: str
    parts: tuple[str | Reference, ...]
    number: float | None = None


def command_definition(system: str, command: str, sysreps: Mapping[str, SysRep]) -> Command | None:
    sysrep = sysreps.get(system)
    return sysrep.command(command) if sysrep is not None else None


def _command(instruction: CommandInstruction, sysreps: Mapping[str, SysRep]) -> Template:
    definition = command_definition(instruction.system, instruction.command, sysreps)
    arguments = [_written(b, definition.arg(b.name) if definition else None) for b in instruction.args]
    label = definition.label if definition is not None else _titled(instruction.command)
    return _command_sentence(label, definition, arguments)


def _written(binding: ArgumentBinding, argument: Argument | None) -> _Argument:
    """An argument as the procedure writes it; a real written as a number is that number."""
    real = argument.type == "real" if argument is not None else _kind(binding.name, None) is not None
    if real and not binding.value.references:
        try:
            return _Argument(binding.name, binding.value.parts, float(str(binding.value)))
        except ValueError:
            pass  # lint refuses such a literal; shown as written
    return _Argument(binding.name, binding.value.parts)


def command_text(system: str, command: str, args: Mapping[str, Any], sysreps: Mapping[str, SysRep]) -> str:
    """A command as sent, in the words of its instruction's sentence, with the values sent.

    The audit log keeps arguments sorted by name, so the SysRep's order is taken back; without the
    SysRep, which argument comes first (the target) is not known, and every one reads "name: value".
    """
    definition = command_definition(system, command, sysreps)
    if definition is None:
        arguments = [_sent(n, v, None) for n, v in args.items()]
        return str(_command_sentence(_titled(command), None, arguments, target=False))
    ordered = in_order(args, definition)
    return str(_command_sentence(definition.label, definition, [_sent(n, v, definition.arg(n)) for n, v in ordered]))


def in_order(args: Mapping[str, Any], definition: Command | None) -> list[tuple[str, Any]]:
    """Arguments in the SysRep's order (any it does not name last), else as given."""
    order = [a.name for a in definition.args] if definition is not None else []
    return sorted(args.items(), key=lambda item: order.index(item[0]) if item[0] in order else len(order))


def _sent(name: str, value: Any, argument: Argument | None) -> _Argument:
    real = argument.type == "real" if argument is not None else _kind(name, None) is not None
    if isinstance(value, (int, float)) and not isinstance(value, bool) and (real or isinstance(value, float)):
        return _Argument(name, (), float(value))
    return _Argument(name, (format_value(value, name=name),))


def _command_sentence(
    label: str, definition: Command | None, arguments: Sequence[_Argument], *, target: bool = True
) -> Template:
    """The sentence of a command; ``target``: the first argument is its target (the arguments are
    in the order the procedure or the SysRep gives them)."""
    args = {a.name: a for a in arguments}
    named = _named_argument(label, list(args))
    first = next(iter(args), None) if target else None  # by convention the target (Fig. 1: affordance_template)
    parts: list[str | Reference] = [label]
    if named is not None:
        parts += [' "', *_shown(args.pop(named), _units(definition, named)), '"']
    if first is not None and first != named:
        parts += [" for ", *_shown(args.pop(first), _units(definition, first))]
    groups: list[list[str | Reference]] = []
    for group, word in ((_POSITION, "position"), (_ORIENTATION, "orientation")):
        if all(name in args for name in group):
            groups.append(_grouped(word, [args.pop(name) for name in group], _units(definition, group[0])))
    rest = [[f"{humanize(a.name)}: ", *_shown(a, _units(definition, a.name))] for a in args.values()] + groups
    if rest:
        parts += [" (", *_join(rest), ")"]
    return _template(parts)


def _shown(argument: _Argument, units: str | None) -> list[str | Reference]:
    kind = _kind(argument.name, units)
    if argument.number is not None:
        return [_number(argument.number, kind) + _suffix(kind, units)]
    written = units or _SI.get(kind or "")
    return [*argument.parts, *([f" {written}"] if written else [])]


def _grouped(word: str, arguments: list[_Argument], units: str | None) -> list[str | Reference]:
    kind = _kind(arguments[0].name, units)
    numbers = [a.number for a in arguments]
    if all(n is not None for n in numbers):
        return [_group(word, [n for n in numbers if n is not None], kind, units)]
    written = units or _SI.get(kind or "")  # a ${...} among them: all as written, in the units sent
    return [f"{word} (", *_join([list(a.parts) for a in arguments]), ")" + (f" {written}" if written else "")]


def _named_argument(label: str, names: list[str]) -> str | None:
    """The argument the label names ("Plan Trajectory" → trajectory), longest run of its words first."""
    words = [w.lower() for w in label.split()[1:]]
    for length in range(len(words), 0, -1):
        for start in range(len(words) - length + 1):
            candidate = "_".join(words[start : start + length])
            if candidate in names:
                return candidate
    return None


def _units(command: Command | None, name: str) -> str | None:
    argument = command.arg(name) if command is not None else None
    return argument.units if argument is not None else None


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


def telemetry_item(system: str, item: str, sysreps: Mapping[str, SysRep]) -> Any:
    sysrep = sysreps.get(system)
    return sysrep.telemetry_item(item) if sysrep is not None else None


def telemetry_label(system: str, item: str, sysreps: Mapping[str, SysRep]) -> str:
    """A telemetry item as the procedure view names it: its SysRep label."""
    found = telemetry_item(system, item, sysreps)
    return found.label if found is not None else _titled(item)


def _subject(subject: Subject, sysreps: Mapping[str, SysRep]) -> str:
    if subject.source == "telemetry":
        return telemetry_label(subject.system or "", subject.name, sysreps)
    if subject.source == "result":
        return f"{humanize(subject.name)} {humanize(subject.field or 'success')}"
    return f"the recorded {humanize(subject.name)}"


_CONDITION_WORDS = (("equals", "is"), ("not_equals", "is not"), ("minimum", "is at least"), ("maximum", "is at most"))
#: Condition.describe()'s symbols, by the condition field each stands for.
_CONDITION_SYMBOLS = {"=": "equals", "≠": "not_equals", "≥": "minimum", "≤": "maximum"}


def _condition(condition: Condition, subject: Subject, sysreps: Mapping[str, SysRep]) -> str:
    """The condition in words ("is at least 2 m"); Condition.describe() has it in symbols."""
    item = telemetry_item(subject.system or "", subject.name, sysreps) if subject.source == "telemetry" else None
    units = f" {item.units}" if item is not None and item.units else ""
    tolerance = f" ± {format_value(condition.tolerance)}" if condition.tolerance is not None else ""
    return " and ".join(
        f"{words} {getattr(condition, name)}{tolerance if name == 'equals' else ''}{units}"
        for name, words in _CONDITION_WORDS
        if getattr(condition, name) is not None
    )


def condition_words(described: str, units: str | None) -> str:
    """A condition as a record keeps it (Condition.describe(): ``= true``, ``≥ 2 and ≤ 5``) in
    the words of the procedure view (``is true``, ``is at least 2 degC and is at most 5 degC``)."""
    words = dict(_CONDITION_WORDS)
    said = []
    for part in described.split(" and "):
        symbol, _, rest = part.partition(" ")
        if symbol in _CONDITION_SYMBOLS:
            part = f"{words[_CONDITION_SYMBOLS[symbol]]} {rest}" + (f" {units}" if units else "")
        said.append(part)
    return " and ".join(said)


def _step(reference: str | None, procedure: Procedure | None) -> str:
    step = procedure.step(reference) if procedure is not None and reference is not None else None
    return f"step {step.number} ({step.title})" if step is not None else f"step {reference}"


# ---- the raw view ----------------------------------------------------------------------------
def raw_form(instruction: Instruction) -> str:
    """Exactly what the instruction does, in the procedure's own terms (the "raw command" view)."""
    if isinstance(instruction, CommandInstruction):
        return _call(f"{instruction.system}.{instruction.command}", {a.name: a.value for a in instruction.args})
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
        called = "call " + _call(instruction.procedure, {a.name: a.value for a in instruction.args})
        return f"{instruction.result} = {called}" if instruction.result else called
    if isinstance(instruction, GoToInstruction):
        return f"goto {instruction.step}"
    if isinstance(instruction, SetInstruction):
        return f"set {instruction.name} = {instruction.value}"
    if isinstance(instruction, WaitInstruction):
        return f"wait {instruction.seconds:g} s"
    return f"{instruction.kind.value}: {instruction.text}"


def raw_call(system: str, command: str, args: Mapping[str, Any]) -> str:
    """A command as sent, as a call with every value in full (the raw view of a sent command)."""
    return _call(f"{system}.{command}", {name: _exact(value) for name, value in args.items()})


def _exact(value: Any) -> object:
    """A value as sent: in full (``0.14999985294229648``), booleans as the procedure writes them."""
    return ("true" if value else "false") if isinstance(value, bool) else value


def _call(callee: str, args: Mapping[str, object]) -> str:
    return f"{callee}({', '.join(f'{name}={value}' for name, value in args.items())})"


def template_json(template: Template) -> list[dict[str, str]]:
    """A sentence for the page: texts and references (``{"ref": "cdra_at.id"}``) to fill in."""
    return [
        {"text": p} if isinstance(p, str) else {"ref": f"{p.name}.{p.field}" if p.field else p.name}
        for p in template.parts
    ]


# ---- values and audit records ----------------------------------------------------------------
def labelled_values(values: Mapping[str, Any], sysrep: SysRep | None = None) -> list[tuple[str, str]]:
    """A command's result values as (label, text): the SysRep's telemetry label and units where a
    value shares a telemetry item's id (``plan_status`` → "Plan Status"), else the key as words.
    A pose is said in its frame (``end_pose`` with ``end_pose_frame``), the frame not again."""
    lines = []
    angles = all(name in values for name in _ORIENTATION)
    for key, value in values.items():
        pose = key.removesuffix("_frame")
        if pose != key and isinstance(values.get(pose), (list, tuple)):
            continue  # said with its pose
        if angles and key in _QUATERNION:
            continue  # roll, pitch and yaw say it in degrees
        item = sysrep.telemetry_item(key) if sysrep is not None else None
        label = item.label if item is not None else humanize(key)
        text = format_value(value, item.units if item is not None else None, name=key)
        frame = values.get(f"{key}_frame")
        lines.append((label, f"{text} in {frame}" if frame and isinstance(value, (list, tuple)) else text))
    return lines


def _not_known(reference: Reference) -> str:
    name = humanize(reference.name) + (f" {humanize(reference.field)}" if reference.field else "")
    return f"‹{name}: not known yet›"  # marked as the page marks a value it does not know yet


def fill_text(text: str, env: dict[str, Any]) -> str:
    """An instruction's sentence as written, with the values ``env`` holds filled in (written as
    :func:`format_value` writes them, by the name of what each measures: ``${cabinet.offset_mm}``
    as millimetres); one the run does not know yet is said to be so in words."""
    texts = []
    for part in Template.parse(text).parts:
        if isinstance(part, str):
            texts.append(part)
            continue
        try:
            texts.append(format_value(lookup(env, part), name=part.field or part.name))
        except KeyError:
            texts.append(_not_known(part))
    return "".join(texts)


def record_refusal(
    value: Any,
    system: str,
    item: str,
    sysreps: Mapping[str, SysRep],
    *,
    listed: Sequence[str] | None = None,
    problem: str = "",
) -> str:
    """Why a recorded value is refused that must be one the system lists in a telemetry item now:
    it is not among them (``listed``: what the system reports), or they could not be read
    (``problem``: "stale", "missing", or what the reading failed with)."""
    sysrep = sysreps.get(system)
    listing = telemetry_label(system, item, sysreps).lower()
    source = f"the {sysrep.name}" if sysrep is not None else system
    if listed is not None:
        return f"{format_value(value)} is not one of the {listing} now; {source} reports {_and(listed)}"
    why = {
        "stale": f"the last report of the {listing} from {source} is stale",
        "missing": f"{source} has not reported the {listing} yet",
    }.get(problem, f"reading the {listing} from {source} failed: {problem}")
    return f"{format_value(value)} cannot be checked now: {why}"


def _and(items: Sequence[str]) -> str:
    """``a, b and c``, as a sentence lists things; "none" for nothing."""
    if len(items) < 2:
        return items[0] if items else "none"
    return f"{', '.join(items[:-1])} and {items[-1]}"
