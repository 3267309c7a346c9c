"""Procedure authoring for the web view's Author page: XML ↔ an editable document, checked by lint.

The page edits a *document*: the procedure's elements as plain JSON (tag, attributes in order,
arguments, text: a record's question, a note's words, or the ``<text>`` sentence of any other
instruction or monitor; a ``<set>``'s value; the declared inputs and outputs), so what it opens it
can save unchanged, and every meaning check stays in one place,
:func:`procedure_language.lint.check_procedure`, the checker ``caretaker lint`` and every run use.
Problems come back with the position of the element they concern (step and item, or an output),
found from the line of that element in the XML this module writes. A document that passes lint
also gets, for each step, what a run started there (``caretaker run --from``) would need given.
"""

from __future__ import annotations

import os
import re
import secrets
from collections.abc import Callable
from pathlib import Path
from typing import Any, cast

from lxml import etree

from console.actions import ActionRefused
from procedure_language.diagnostics import ProcedureError
from procedure_language.limits import RED, YELLOW, Limits
from procedure_language.lint import CheckedProcedure, check_procedure, section_needs
from procedure_language.model import Location
from procedure_language.sysrep import SysRep

__all__ = [
    "check_document",
    "document_to_xml",
    "procedure_signatures",
    "read_document",
    "save_document",
    "sysrep_palette",
]

_FILE_NAME = re.compile(r"^[A-Za-z0-9_][A-Za-z0-9_.-]*\.xml$")
_WITH_ARGS = ("command", "call")
_WITH_TEXT = ("record", "manual", "note", "caution", "warning")


def sysrep_palette(sysreps: dict[str, SysRep]) -> list[dict[str, Any]]:
    """Every SysRep with its commands (typed arguments) and telemetry, for the palette."""

    def value(arg: Any) -> dict[str, Any]:
        return {
            "name": arg.name,
            "type": arg.type,
            "min": arg.min,
            "max": arg.max,
            "enum": list(arg.enum) if arg.enum else None,
            "units": arg.units,
        }

    return [
        {
            "id": s.id,
            "name": s.name,
            "file": Path(s.path).name,
            "commands": [
                {"id": c.id, "label": c.label, "hazardous": c.hazardous, "args": [value(a) for a in c.args]}
                for c in s.commands
            ],
            "telemetry": [
                {"id": t.id, "label": t.label, "type": t.type, "limits": _limits(t.limits)} for t in s.telemetry
            ],
        }
        for s in sorted(sysreps.values(), key=lambda s: s.id)
    ]


def _limits(limits: Limits | None) -> dict[str, str | None] | None:
    """The limits a monitor may name (``limit="red"``/``"yellow"``), in words; None: the item has none."""
    if limits is None:
        return None
    yellow = limits.equals is None and (limits.yellow_low is not None or limits.yellow_high is not None)
    return {RED: limits.describe(RED), YELLOW: limits.describe(YELLOW) if yellow else None}


def procedure_signatures(directory: Path, names: list[str]) -> dict[str, dict[str, list[dict[str, str]]]]:
    """The declared inputs and outputs (name, type) of each procedure a ``call`` may name: its
    arguments are prefilled from the inputs, and ``${result.output}`` offered from the outputs.

    A file that cannot be read is left out: the page then takes free-form arguments, and lint
    reports the broken callee on the call itself.
    """
    signatures: dict[str, dict[str, list[dict[str, str]]]] = {}
    for name in names:
        try:
            document = read_document(directory / name)
        except ActionRefused:
            continue
        signatures[name] = {
            kind: [{"name": d.get("name", ""), "type": d.get("type", "string")} for d in document[kind]]
            for kind in ("inputs", "outputs")
        }
    return signatures


# ---- XML → document ---------------------------------------------------------------------------
def _item(element: etree._Element) -> dict[str, Any]:
    item: dict[str, Any] = {"kind": element.tag, "attrs": dict(element.attrib)}
    if element.tag in _WITH_ARGS:
        item["args"] = [{"name": arg.get("name", ""), "value": arg.text or ""} for arg in element if arg.tag == "arg"]
    if element.tag in _WITH_TEXT:
        item["text"] = " ".join((element.text or "").split())
    elif element.tag == "set":  # its value is its content (its sentence, if any, the text attribute)
        item["value"] = (element.text or "").strip()
    elif element.find("text") is not None:  # the sentence the instruction reads as
        item["text"] = " ".join((element.findtext("text") or "").split())
    return item


def read_document(path: Path) -> dict[str, Any]:
    """The editable document of a procedure file."""
    try:
        root = etree.parse(str(path), etree.XMLParser(remove_comments=True)).getroot()
    except (OSError, etree.XMLSyntaxError) as exc:
        raise ActionRefused(422, f"{path.name}: cannot be opened: {exc}") from None
    document: dict[str, Any] = {
        "attrs": dict(root.attrib),
        "description": "",
        "uses": [],
        "responds_to": [],
        "inputs": [],
        "outputs": [],
        "steps": [],
    }
    for child in root:
        if child.tag == "description":
            document["description"] = " ".join((child.text or "").split())
        elif child.tag == "uses":
            document["uses"].append(child.get("system", ""))
        elif child.tag == "responds-to":  # kept as written: the page does not edit it
            document["responds_to"].append({"attrs": dict(child.attrib), "text": " ".join((child.text or "").split())})
        elif child.tag in ("input", "output"):
            document[f"{child.tag}s"].append(dict(child.attrib))
        elif child.tag == "step":
            document["steps"].append({"attrs": dict(child.attrib), "items": [_item(item) for item in child]})
    return document


# ---- document → XML ---------------------------------------------------------------------------
def _text(value: Any) -> str:
    return "" if value is None else str(value)


def _element(parent: etree._Element, tag: str, attrs: dict[str, Any]) -> etree._Element:
    element = etree.SubElement(parent, tag)
    for name, value in attrs.items():
        if _text(value) != "":  # an empty field means "not given", never an empty attribute
            element.set(str(name), _text(value))
    return element


def _tree(document: dict[str, Any]) -> etree._Element:
    try:
        root = etree.Element("procedure")
        for name, value in document.get("attrs", {}).items():
            if _text(value) != "":
                root.set(str(name), _text(value))
        if document.get("description"):
            etree.SubElement(root, "description").text = _text(document["description"])
        for system in document.get("uses", []):
            _element(root, "uses", {"system": system})
        for response in document.get("responds_to", []):
            _element(root, "responds-to", response.get("attrs", {})).text = _text(response.get("text"))
        for kind in ("input", "output"):
            for declared in document.get(f"{kind}s", []):
                _element(root, kind, declared)
        for step in document.get("steps", []):
            step_element = _element(root, "step", step.get("attrs", {}))
            for item in step.get("items", []):
                element = _element(step_element, str(item["kind"]), item.get("attrs", {}))
                if item["kind"] not in _WITH_TEXT and item.get("text"):
                    etree.SubElement(element, "text").text = _text(item["text"])
                for arg in item.get("args", []) if item["kind"] in _WITH_ARGS else []:
                    _element(element, "arg", {"name": arg.get("name")}).text = _text(arg.get("value"))
                if item["kind"] in _WITH_TEXT:
                    element.text = _text(item.get("text"))
                elif item["kind"] == "set":
                    element.text = _text(item.get("value"))
    except (AttributeError, KeyError, TypeError, ValueError) as exc:
        raise ActionRefused(400, f"the document is malformed: {type(exc).__name__}: {exc}") from None
    return root


def document_to_xml(document: dict[str, Any]) -> str:
    """The procedure XML of a document (what Save writes)."""
    root = _tree(document)
    etree.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + etree.tostring(root, encoding="unicode") + "\n"


#: Where a problem is on the page: ``[step, item]`` (item -1: the step itself), or ``["outputs", n]``.
Place = list[int | str]


def _placer(xml: str, scratch: Path) -> Callable[[Location], Place | None]:
    """Where on the page a position in ``xml`` (checked as the file ``scratch``) is: the last output,
    step or item that starts at or before its line; None in the procedure's head, or in another file."""
    root = etree.fromstring(xml.encode())

    def line(element: etree._Element) -> int:
        return cast(int | None, element.sourceline) or 0  # lxml-stubs mistype sourceline

    starts: list[tuple[int, Place]] = [(line(o), ["outputs", n]) for n, o in enumerate(root.findall("output"))]
    for s, step in enumerate(root.findall("step")):
        starts.append((line(step), [s, -1]))
        starts += [(line(item), [s, i]) for i, item in enumerate(step)]

    def place(where: Location) -> Place | None:
        owners = [at for start, at in starts if start <= where.line] if where.path == str(scratch) else []
        return owners[-1] if owners else None

    return place


def _sections(checked: CheckedProcedure, place: Callable[[Location], Place | None]) -> list[dict[str, Any]]:
    """For each step, what a run started there (``--from``) must be given: what only the steps it skips bind."""
    return [
        {
            "from": step.id,
            "needs": [
                {"name": u.name, "line": u.where.line, "at": place(u.where)} for u in section_needs(checked, step.id)
            ],
        }
        for step in checked.procedure.steps
    ]


def check_document(document: dict[str, Any], directory: Path, sysreps: dict[str, SysRep]) -> dict[str, Any]:
    """Lint the document as if saved in ``directory``: its XML, its problems placed on the page, and
    (when there are none) what a start at each step needs."""
    xml = document_to_xml(document)
    scratch = directory / f".author-{secrets.token_hex(4)}.xml"  # calls resolve relative to the directory
    checked: CheckedProcedure | None = None
    try:
        scratch.write_text(xml, encoding="utf-8")
        checked, problems = check_procedure(scratch, sysreps), []
    except ProcedureError as exc:
        problems = exc.problems
    finally:
        scratch.unlink(missing_ok=True)
    place = _placer(xml, scratch)
    placed = [
        {
            "line": problem.where.line,
            "col": problem.where.col,
            "message": problem.message if problem.where.path == str(scratch) else str(problem),
            "at": place(problem.where),
        }
        for problem in problems
    ]
    return {"xml": xml, "problems": placed, "sections": _sections(checked, place) if checked is not None else None}


def save_document(
    document: dict[str, Any], name: str, directory: Path, sysreps: dict[str, SysRep], *, replace: bool = False
) -> dict[str, Any]:
    """Write the document as ``directory/name`` if lint finds nothing; ActionRefused otherwise.

    An existing file is replaced only when ``replace`` says the author confirmed it (409 otherwise).
    """
    if not _FILE_NAME.match(name):
        raise ActionRefused(400, f"file name {name!r}: use letters, digits, _ . - and end with .xml")
    checked = check_document(document, directory, sysreps)
    if checked["problems"]:
        raise ActionRefused(422, f"{name} not saved: lint found {len(checked['problems'])} problem(s); fix them first")
    target = directory / name
    if (
        replace
    ):  # a whole new file put in place: a reader never sees half of it, a link is replaced, not written through
        scratch = directory / f".author-{secrets.token_hex(4)}.xml"
        scratch.write_text(checked["xml"], encoding="utf-8")
        os.replace(scratch, target)
        return {"saved": name, "xml": checked["xml"]}
    try:
        with target.open("x", encoding="utf-8") as out:  # "x": never over a file, even one written meanwhile
            out.write(checked["xml"])
    except FileExistsError:
        raise ActionRefused(409, f"{name} already exists: confirm to replace it, or save under another name") from None
    return {"saved": name, "xml": checked["xml"]}
