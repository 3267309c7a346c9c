"""Procedure XML → :mod:`procedure_language.model`, with file:line:col for every element and attribute.

Loading is two passes: the XSD (:mod:`procedure_language.schema`) checks structure, then this module checks
what a schema cannot say (a condition needs a test, a wait needs a duration or a condition, an
``if`` reads exactly one thing) and numbers steps and instructions. Meaning against SysReps is
:mod:`procedure_language.lint`'s job.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from lxml import etree

from procedure_language import schema
from procedure_language.diagnostics import Problem, ProcedureError
from procedure_language.limits import Persistence, parse_persistence
from procedure_language.model import (
    ArgumentBinding,
    BranchInstruction,
    CallInstruction,
    CommandInstruction,
    Condition,
    GoToInstruction,
    Input,
    Instruction,
    Kind,
    Location,
    ManualInstruction,
    Monitor,
    Notice,
    Output,
    Procedure,
    RecordInstruction,
    RespondsTo,
    SetInstruction,
    Step,
    Subject,
    Template,
    VerifyInstruction,
    WaitInstruction,
)
from procedure_language.sysrep import check_value
from procedure_language.xml_reader import Positions, read_xml

__all__ = ["load_procedure", "parse_procedure"]

_NOTICES = ("note", "caution", "warning")
#: The longest wait or timeout a procedure may state (a year): larger is a slip, and would overflow timers.
MAX_SECONDS = 365 * 24 * 3600.0
_CONDITION_ATTRIBUTES = ("equals", "not-equals", "min", "max", "tolerance")


class _Builder:
    def __init__(self, path: Path, positions: Positions) -> None:
        self.path = path
        self.pos = positions
        self.problems: list[Problem] = []

    def fail(self, where: Location, message: str) -> None:
        self.problems.append(Problem(where, message))

    def attrs(self, el: etree._Element) -> dict[str, Location]:
        return {str(name): self.pos.attribute(el, str(name)) for name in el.attrib}

    def required(self, el: etree._Element, name: str) -> str:
        """An attribute the schema requires (validation ran first, so it is there)."""
        value = el.get(name)
        if value is None:  # the schema and this builder disagree: report it, never crash
            self.fail(self.pos.element(el), f'<{el.tag}> needs {name}="..."')
            return ""
        return value

    def procedure(self, root: etree._Element) -> Procedure:
        uses = tuple((self.required(u, "system"), self.pos.attribute(u, "system")) for u in root.findall("uses"))
        inputs = tuple(
            Input(self.required(i, "name"), i.get("type", "string"), self.pos.attribute(i, "name"))
            for i in root.findall("input")
        )
        outputs = tuple(
            Output(self.required(o, "name"), o.get("type", "string"), self.pos.attribute(o, "name"))
            for o in root.findall("output")
        )
        for n, output in enumerate(outputs):
            first = next((o for o in outputs[:n] if o.name == output.name), None)
            if first is not None:
                self.fail(output.where, f"output {output.name!r} is declared twice (first at line {first.where.line})")
        steps = []
        seen_ids: dict[str, Location] = {}
        for number, el in enumerate(root.findall("step"), start=1):
            step = self.step(el, number)
            if step.id in seen_ids and el.get("id"):
                self.fail(
                    self.pos.attribute(el, "id"),
                    f"duplicate step id {step.id!r} (first at line {seen_ids[step.id].line})",
                )
            seen_ids.setdefault(step.id, step.where)
            steps.append(step)
        description = root.findtext("description") or ""
        responds_to = tuple(self.responds_to(r) for r in root.findall("responds-to"))
        return Procedure(
            id=self.required(root, "id"),
            title=self.required(root, "title"),
            version=self.required(root, "version"),
            path=str(self.path),
            uses=uses,
            inputs=inputs,
            steps=tuple(steps),
            where=self.pos.element(root),
            description=" ".join(description.split()),
            outputs=outputs,
            responds_to=responds_to,
        )

    def responds_to(self, el: etree._Element) -> RespondsTo:
        """A ``<responds-to>``: the telemetry limit it answers, and in words why."""
        where = self.pos.element(el)
        text = _clean(el.text)
        if not text:
            self.fail(where, "<responds-to> needs text: why the item at that limit calls for this procedure")
        return RespondsTo(
            system=self.required(el, "system"),
            telemetry=self.required(el, "telemetry"),
            limit=self.required(el, "limit"),
            text=text,
            where=where,
            attrs=self.attrs(el),
        )

    def step(self, el: etree._Element, number: int) -> Step:
        instructions: list[Instruction] = []
        pending: list[Notice] = []
        monitors: list[Monitor] = []
        for child in el:
            if not isinstance(child.tag, str):
                continue  # comments
            if child.tag == "monitor":
                monitors.append(self.monitor(child, number))
                continue
            if child.tag in _NOTICES:
                pending.append(Notice(child.tag, _clean(child.text), self.pos.element(child)))
                continue
            instruction = self.instruction(child, f"{number}.{len(instructions) + 1}", tuple(pending))
            pending = []
            instructions.append(instruction)
        where = self.pos.element(el)
        if not instructions:
            self.fail(where, f"step {number} has no instruction (notes alone cannot be performed)")
        return Step(
            number,
            el.get("id") or str(number),
            self.required(el, "title"),
            tuple(instructions),
            where,
            tuple(pending),
            contingency=_bool(el.get("contingency", "false")),
            monitors=tuple(monitors),
        )

    def monitor(self, el: etree._Element, step: int) -> Monitor:
        """A ``<monitor>``: a condition or a SysRep limit, never both."""
        where = self.pos.element(el)
        condition = self.condition(el, required=False)
        limit = el.get("limit")
        if (condition is None) == (limit is None):
            self.fail(
                where, '<monitor> watches a condition (equals, not-equals, min, max) or limit="red|yellow": one of them'
            )
        action, _, goto = el.get("on-violation", "halt").partition(":")
        persistence: Persistence | None = None
        if el.get("persistence") is not None:
            try:
                persistence = parse_persistence(el.get("persistence"))
            except ValueError as exc:
                self.fail(self.pos.attribute(el, "persistence"), str(exc))
        sentence = el.find("text")
        return Monitor(
            system=self.required(el, "system"),
            telemetry=self.required(el, "telemetry"),
            condition=condition,
            limit=limit,
            scope=el.get("scope", "step"),
            on_violation=action,
            goto=goto or None,
            persistence=persistence,
            text=_clean(sentence.text if sentence is not None else ""),
            step=step,
            where=where,
            attrs=self.attrs(el),
        )

    def instruction(self, el: etree._Element, number: str, notices: tuple[Notice, ...]) -> Instruction:
        common: dict[str, Any] = dict(
            number=number,
            text=_clean(el.get("text") or ""),
            automatable=_bool(el.get("automatable", "true")),
            where=self.pos.element(el),
            notices=notices,
            attrs=self.attrs(el),
        )
        sentence = el.find("text")  # the sentence the instruction reads as, written as an element
        if sentence is not None:
            if el.get("text") is not None:
                self.fail(
                    self.pos.element(sentence), "the text is given twice: keep the text attribute or the <text> element"
                )
            common["text"], common["attrs"]["text"] = _clean(sentence.text), self.pos.text(sentence)
        tag = el.tag
        if tag == "command":
            return CommandInstruction(
                kind=Kind.COMMAND,
                system=self.required(el, "system"),
                command=self.required(el, "name"),
                args=self.arguments(el),
                result=el.get("result"),
                hazardous=_bool(el.get("hazardous", "false")),
                on_failure=el.get("on-failure"),
                **common,
            )
        if tag == "verify":
            subject = Subject("telemetry", self.required(el, "telemetry"), system=self.required(el, "system"))
            return VerifyInstruction(
                kind=Kind.VERIFY,
                subject=subject,
                condition=self.condition(el, required=True) or Condition(),
                timeout=self.seconds(el, "timeout", "10"),
                on_failure=el.get("on-failure"),
                **common,
            )
        if tag == "wait":
            return self.wait(el, common)
        if tag == "record":
            return self.record(el, common)
        if tag == "manual":
            common["text"] = _clean(el.text)
            if not common["text"]:
                self.fail(common["where"], "manual instruction needs text saying what the operator must do")
            return ManualInstruction(kind=Kind.MANUAL, **common)
        if tag == "if":
            return BranchInstruction(
                kind=Kind.BRANCH,
                subject=self.subject(el),
                condition=self.condition(el, required=True) or Condition(),
                goto=self.required(el, "goto"),
                else_goto=el.get("else"),
                **common,
            )
        if tag == "goto":
            return GoToInstruction(kind=Kind.GOTO, step=self.required(el, "step"), **common)
        if tag == "set":
            value = (el.text or "").strip()
            if not value:
                self.fail(common["where"], f"<set name={el.get('name')!r}> needs a value: write it inside the element")
            common["attrs"].setdefault("value", self.pos.text(el))
            return SetInstruction(kind=Kind.SET, name=self.required(el, "name"), value=Template.parse(value), **common)
        procedure = self.required(el, "procedure")
        return CallInstruction(
            kind=Kind.CALL,
            procedure=procedure,
            args=self.arguments(el),
            resolved_path=str((self.path.parent / procedure).resolve()),
            result=el.get("result"),
            **common,
        )

    def arguments(self, el: etree._Element) -> tuple[ArgumentBinding, ...]:
        args: list[ArgumentBinding] = []
        for arg in el.findall("arg"):
            name = self.required(arg, "name")
            if any(a.name == name for a in args):
                self.fail(self.pos.attribute(arg, "name"), f"argument {name!r} given twice")
            args.append(ArgumentBinding(name, Template.parse((arg.text or "").strip()), self.pos.text(arg)))
        return tuple(args)

    def seconds(self, el: etree._Element, name: str, default: str = "0") -> float:
        """A duration attribute (the schema made it a decimal ≥ 0); an absurd one is an error, not a hang."""
        value = float(el.get(name, default))
        if not value <= MAX_SECONDS:
            self.fail(self.pos.attribute(el, name), f"{name} must be at most {MAX_SECONDS:g} s, got {el.get(name)}")
            return MAX_SECONDS
        return value

    def condition(self, el: etree._Element, *, required: bool) -> Condition | None:
        if not any(el.get(a) is not None for a in ("equals", "not-equals", "min", "max")):
            if required:
                self.fail(self.pos.element(el), f"<{el.tag}> needs a condition: equals, not-equals, min or max")
            return None
        if el.get("tolerance") is not None and el.get("equals") is None:
            self.fail(self.pos.attribute(el, "tolerance"), 'tolerance applies to equals; add equals="..."')
        tolerance = el.get("tolerance")
        return Condition(
            equals=el.get("equals"),
            not_equals=el.get("not-equals"),
            minimum=el.get("min"),
            maximum=el.get("max"),
            tolerance=float(tolerance) if tolerance is not None else None,
        )

    def subject(self, el: etree._Element) -> Subject:
        given = [a for a in ("telemetry", "input", "result") if el.get(a) is not None]
        where = self.pos.element(el)
        if len(given) != 1:
            self.fail(
                where,
                "<if> reads exactly one of telemetry (with system), input or result; "
                f"found {', '.join(given) or 'none'}",
            )
            return Subject("input", el.get("input") or "?")
        source = given[0]
        if source == "telemetry":
            if el.get("system") is None:
                self.fail(where, '<if telemetry=...> needs system="..."')
            return Subject("telemetry", self.required(el, "telemetry"), system=el.get("system"))
        if el.get("system") is not None:
            self.fail(self.pos.attribute(el, "system"), f"system applies to telemetry, not to {source}")
        if source == "input":
            return Subject("input", self.required(el, "input"))
        name, _, field = self.required(el, "result").partition(".")
        if not re.fullmatch(r"[A-Za-z_]\w*", name) or not re.fullmatch(r"[A-Za-z_]\w*", field):
            self.fail(
                self.pos.attribute(el, "result"),
                f"result must be NAME.FIELD (e.g. plan.success), got {el.get('result')!r}",
            )
        return Subject("result", name, field=field or "success")

    def wait(self, el: etree._Element, common: dict[str, Any]) -> WaitInstruction:
        seconds = el.get("seconds")
        condition = self.condition(el, required=False)
        reads = el.get("telemetry") is not None or el.get("system") is not None
        where = common["where"]
        if seconds is not None and (reads or condition is not None):
            self.fail(where, "<wait> takes either seconds or a telemetry condition, not both")
        if seconds is None and not (el.get("telemetry") and el.get("system") and condition is not None):
            self.fail(where, '<wait> needs seconds="..." or system, telemetry and a condition (equals, min, ...)')
        subject = Subject("telemetry", el.get("telemetry") or "", system=el.get("system")) if reads else None
        return WaitInstruction(
            kind=Kind.WAIT,
            seconds=self.seconds(el, "seconds") if seconds is not None else None,
            subject=subject,
            condition=condition,
            timeout=self.seconds(el, "timeout", "60"),
            on_failure=el.get("on-failure"),
            **common,
        )

    def record(self, el: etree._Element, common: dict[str, Any]) -> RecordInstruction:
        type_name = el.get("type", "string")
        common["text"] = _clean(el.text)
        if not common["text"]:
            self.fail(common["where"], "record needs text: the question the operator answers")
        for bound in ("min", "max"):
            if el.get(bound) is not None and type_name not in ("integer", "real"):
                self.fail(self.pos.attribute(el, bound), f"{bound} applies to integer or real records, not {type_name}")
        pattern = el.get("pattern")
        if pattern is not None:
            try:
                re.compile(pattern)
            except re.error as exc:
                self.fail(self.pos.attribute(el, "pattern"), f"pattern is not a valid regular expression: {exc}")
        one_of = el.get("one-of")
        choices = tuple(c.strip() for c in one_of.split(",")) if one_of else None
        listed = el.get("one-of-telemetry")
        one_of_telemetry = None
        if listed is not None:
            system, dot, item = listed.partition(".")
            if not (system and dot and item) or "." in item:
                self.fail(
                    self.pos.attribute(el, "one-of-telemetry"),
                    f"one-of-telemetry names a telemetry item as system.item, got {listed!r}",
                )
            one_of_telemetry = (system, item)
        minimum, maximum = el.get("min"), el.get("max")
        record = RecordInstruction(
            kind=Kind.RECORD,
            name=self.required(el, "name"),
            type=type_name,
            minimum=float(minimum) if minimum is not None else None,
            maximum=float(maximum) if maximum is not None else None,
            pattern=pattern,
            choices=choices,
            one_of_telemetry=one_of_telemetry,
            **{**common, "automatable": False},
        )
        for choice in choices or ():
            try:
                check_value(record.name, type_name, choice)
            except ValueError as exc:
                self.fail(self.pos.attribute(el, "one-of"), f"one-of: {exc}")
        return record


def _bool(text: str) -> bool:
    return text.strip() in ("true", "1")


def _clean(text: str | None) -> str:
    """Collapse the indentation and line breaks of text written across lines."""
    return " ".join((text or "").split())


def parse_procedure(path: str | Path) -> tuple[Procedure | None, list[Problem]]:
    """Read, parse and check the structure of one procedure; the model is None when it has errors."""
    path = Path(path)
    tree, source, problems = read_xml(path)
    if tree is None:
        return None, problems
    positions = Positions(source)
    problems = schema.validate(tree, positions)
    if problems:
        return None, problems
    builder = _Builder(path, positions)
    procedure = builder.procedure(tree.getroot())
    return (None if builder.problems else procedure), builder.problems


def load_procedure(path: str | Path) -> Procedure:
    """Parse one procedure or raise ProcedureError listing its structural errors."""
    procedure, problems = parse_procedure(path)
    if procedure is None:
        raise ProcedureError(problems)
    return procedure
