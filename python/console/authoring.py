"""Procedure authoring for the web view's Author page: XML ↔ an editable document, checked by lint.

The page edits a *document*: the procedure's elements as plain JSON (tag, attributes in order,
arguments, text: a record's question, a note's words, or the ``<text>`` sentence of any other
instruction), so what it opens it can save unchanged, and every meaning check stays in one place,
:func:`procedure_language.lint.lint_file`, the checker ``caretaker lint`` uses. Problems come back with the
position (step, item) of the element they concern, found from the line of that element in the XML
this module writes.
"""

from __future__ import annotations

import os
import re
import secrets
from pathlib import Path
from typing import Any, cast

from lxml import etree

from console.actions import ActionRefused
from procedure_language.lint import lint_file
from procedure_language.sysrep import SysRep

__all__ = ["check_document", "document_to_xml", "procedure_inputs", "read_document", "save_document", "sysrep_palette"]

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
            "telemetry": [{"id": t.id, "label": t.label, "type": t.type} for t in s.telemetry],
        }
        for s in sorted(sysreps.values(), key=lambda s: s.id)
    ]


def procedure_inputs(directory: Path, names: list[str]) -> dict[str, list[dict[str, str]]]:
    """The declared inputs (name, type) of each procedure a ``call`` may name, to prefill its arguments.

    A file that cannot be read is left out: the page then takes free-form arguments, and lint
    reports the broken callee on the call itself.
    """
    signatures: dict[str, list[dict[str, str]]] = {}
    for name in names:
        try:
            inputs = read_document(directory / name)["inputs"]
        except ActionRefused:
            continue
        signatures[name] = [{"name": i.get("name", ""), "type": i.get("type", "string")} for i in inputs]
    return signatures


# ---- XML → document ---------------------------------------------------------------------------
def _item(element: etree._Element) -> dict[str, Any]:
    item: dict[str, Any] = {"kind": element.tag, "attrs": dict(element.attrib)}
    if element.tag in _WITH_ARGS:
        item["args"] = [{"name": arg.get("name", ""), "value": arg.text or ""} for arg in element if arg.tag == "arg"]
    if element.tag in _WITH_TEXT:
        item["text"] = " ".join((element.text or "").split())
    elif element.find("text") is not None:  # the sentence the instruction reads as
        item["text"] = " ".join((element.findtext("text") or "").split())
    return item


def read_document(path: Path) -> dict[str, Any]:
    """The editable document of a procedure file."""
    try:
        root = etree.parse(str(path), etree.XMLParser(remove_comments=True)).getroot()
    except (OSError, etree.XMLSyntaxError) as exc:
        raise ActionRefused(422, f"{path.name}: cannot be opened: {exc}") from None
    document: dict[str, Any] = {"attrs": dict(root.attrib), "description": "", "uses": [], "inputs": [], "steps": []}
    for child in root:
        if child.tag == "description":
            document["description"] = " ".join((child.text or "").split())
        elif child.tag == "uses":
            document["uses"].append(child.get("system", ""))
        elif child.tag == "input":
            document["inputs"].append(dict(child.attrib))
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


def _tree(document: dict[str, Any]) -> tuple[etree._Element, list[tuple[etree._Element, tuple[int, int]]]]:
    try:
        root = etree.Element("procedure")
        for name, value in document.get("attrs", {}).items():
            if _text(value) != "":
                root.set(str(name), _text(value))
        if document.get("description"):
            etree.SubElement(root, "description").text = _text(document["description"])
        for system in document.get("uses", []):
            _element(root, "uses", {"system": system})
        for declared in document.get("inputs", []):
            _element(root, "input", declared)
        positions: list[tuple[etree._Element, tuple[int, int]]] = []
        for s, step in enumerate(document.get("steps", [])):
            step_element = _element(root, "step", step.get("attrs", {}))
            positions.append((step_element, (s, -1)))
            for i, item in enumerate(step.get("items", [])):
                element = _element(step_element, str(item["kind"]), item.get("attrs", {}))
                if item["kind"] not in _WITH_TEXT and item.get("text"):
                    etree.SubElement(element, "text").text = _text(item["text"])
                for arg in item.get("args", []) if item["kind"] in _WITH_ARGS else []:
                    _element(element, "arg", {"name": arg.get("name")}).text = _text(arg.get("value"))
                if item["kind"] in _WITH_TEXT:
                    element.text = _text(item.get("text"))
                positions.append((element, (s, i)))
    except (AttributeError, KeyError, TypeError, ValueError) as exc:
        raise ActionRefused(400, f"the document is malformed: {type(exc).__name__}: {exc}") from None
    return root, positions


def document_to_xml(document: dict[str, Any]) -> str:
    """The procedure XML of a document (what Save writes)."""
    root, _ = _tree(document)
    etree.indent(root, space="  ")
    return '<?xml version="1.0" encoding="UTF-8"?>\n' + etree.tostring(root, encoding="unicode") + "\n"


def _line_positions(xml: str) -> list[tuple[int, tuple[int, int]]]:
    """(line, (step, item)) of every step and item in ``xml`` as written, in order."""
    root = etree.fromstring(xml.encode())
    found: list[tuple[int, tuple[int, int]]] = []
    for s, step in enumerate(root.findall("step")):
        found.append((cast(int | None, step.sourceline) or 0, (s, -1)))  # lxml-stubs mistype sourceline
        for i, item in enumerate(step):
            found.append((cast(int | None, item.sourceline) or 0, (s, i)))
    return found


def check_document(document: dict[str, Any], directory: Path, sysreps: dict[str, SysRep]) -> dict[str, Any]:
    """Lint the document as if saved in ``directory``: its XML and its problems, placed on items."""
    xml = document_to_xml(document)
    scratch = directory / f".author-{secrets.token_hex(4)}.xml"  # calls resolve relative to the directory
    try:
        scratch.write_text(xml, encoding="utf-8")
        problems = lint_file(scratch, sysreps)
    finally:
        scratch.unlink(missing_ok=True)
    lines = _line_positions(xml)
    placed = []
    for problem in problems:
        at = None
        if problem.where.path == str(scratch):
            owners = [position for line, position in lines if line <= problem.where.line]
            at = list(owners[-1]) if owners else None
        message = problem.message if problem.where.path == str(scratch) else str(problem)
        placed.append({"line": problem.where.line, "col": problem.where.col, "message": message, "at": at})
    return {"xml": xml, "problems": placed}


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
