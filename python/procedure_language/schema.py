"""Structural validation of procedure XML against ``procedures/schema/procedure.xsd`` (lxml).

libxml2's messages speak of the schema machinery ("No matching global declaration", "atomic type
'xs:decimal'", a list of expected elements cut short). Each is rewritten here in the procedure's
own words: which element or attribute, and what is allowed there — read from the XSD itself, so
the messages follow the schema when it changes.
"""

from __future__ import annotations

import difflib
import re
import threading
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import lru_cache
from pathlib import Path
from typing import cast

from lxml import etree

from procedure_language.diagnostics import Problem
from procedure_language.xml_reader import Positions

__all__ = ["ROOT", "SCHEMA_PATH", "validate"]

SCHEMA_PATH = Path(__file__).resolve().parents[2] / "procedures" / "schema" / "procedure.xsd"
ROOT = "procedure"
_XS = "{http://www.w3.org/2001/XMLSchema}"
_validation_lock = threading.Lock()  # one XMLSchema and its error_log are shared: validate one file at a time

#: What a value of each schema type must look like, as an author reads it.
_TYPE_WORDS = {
    "identifier": "a name of letters, digits and _ that does not start with a digit",
    "stepRef": "a step id or number",
    "valueType": "string, boolean, integer or real",
    "seconds": "a number of seconds, 0 or more",
    "limitState": "red or yellow",
    "monitorScope": "step or procedure",
    "onViolation": "hold, halt or goto:STEP",
    "text": "text that is not empty",
    "xs:boolean": "true or false",
    "xs:decimal": "a decimal number (such as 2.5)",
    "xs:string": "text",
}


@dataclass
class _Element:
    """What the schema allows in one element: child elements, attributes, text."""

    children: list[str] = field(default_factory=list)
    ordered: bool = False  # a sequence: children must come in this order
    required_children: list[str] = field(default_factory=list)
    attributes: dict[str, str] = field(default_factory=dict)  # name → type
    required: list[str] = field(default_factory=list)
    text: bool = False


@lru_cache(maxsize=1)
def _schema() -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(SCHEMA_PATH)))


@lru_cache(maxsize=1)
def _elements() -> dict[str, _Element]:
    """Every element the XSD declares, by name (names are unique in this schema)."""
    root = etree.parse(str(SCHEMA_PATH)).getroot()
    types = {t.get("name"): t for t in root.findall(f"{_XS}complexType")}
    groups = {g.get("name"): g for g in root.findall(f"{_XS}attributeGroup")}
    elements: dict[str, _Element] = {}
    for declaration in root.iter(f"{_XS}element"):
        name = declaration.get("name")
        if name is None:
            continue
        type_name = declaration.get("type", "")
        complex_type = declaration.find(f"{_XS}complexType")
        if complex_type is None:
            complex_type = types.get(type_name)
        spec = _Element(text=complex_type is None)
        if complex_type is not None:
            _describe(complex_type, groups, spec)
        elements[name] = spec
    return elements


def _describe(complex_type: etree._Element, groups: dict[str | None, etree._Element], spec: _Element) -> None:
    for particle in (complex_type.find(f"{_XS}sequence"), complex_type.find(f"{_XS}choice")):
        if particle is None:
            continue
        spec.ordered = particle.tag == f"{_XS}sequence"
        children = particle.findall(f"{_XS}element")
        spec.children = [str(e.get("name")) for e in children]
        if spec.ordered:
            spec.required_children = [str(e.get("name")) for e in children if e.get("minOccurs") != "0"]
        elif particle.get("minOccurs") != "0":
            spec.required_children = list(spec.children)
    holders = [complex_type]
    content = complex_type.find(f"{_XS}simpleContent")
    if content is not None:
        spec.text = True
        holders += list(content)
    for holder in holders:
        for item in holder:
            if item.tag == f"{_XS}attributeGroup":
                item = groups.get(item.get("ref"), item)
                attributes = item.findall(f"{_XS}attribute")
            elif item.tag == f"{_XS}attribute":
                attributes = [item]
            else:
                continue
            for attribute in attributes:
                name = str(attribute.get("name"))
                spec.attributes[name] = attribute.get("type", "xs:string")
                if attribute.get("use") == "required":
                    spec.required.append(name)


def _tags(names: list[str]) -> str:
    return ", ".join(f"<{n}>" for n in names)


_ELEMENT = re.compile(r"^Element '([^']+)'(?:, attribute '([^']+)')?: (.*)$", re.DOTALL)
_VALUE = re.compile(r"'([^']*)' is not a valid value|The value '([^']*)'")
_REQUIRED = re.compile(r"The attribute '([^']+)' is required")


class _Rewriter:
    """Turns libxml2's schema messages into the procedure's words, at the right file position."""

    def __init__(self, tree: etree._ElementTree, positions: Positions) -> None:
        self.tree = tree
        self.positions = positions
        self.elements = _elements()

    def node(self, entry: etree._LogEntry) -> etree._Element | None:
        try:
            found = self.tree.xpath(entry.path) if entry.path else []
        except etree.XPathError:
            return None
        return found[0] if isinstance(found, list) and found and isinstance(found[0], etree._Element) else None

    def problem(self, entry: etree._LogEntry) -> Problem:
        node = self.node(entry)
        where = self.positions.element(node) if node is not None else self.positions.source.at(entry.line, entry.column)
        parsed = _ELEMENT.match(entry.message.strip())
        if parsed is None:
            return Problem(where, entry.message.strip())
        tag, attribute, said = parsed.groups()
        spec = self.elements.get(tag, _Element())
        if attribute is not None:
            if node is not None:
                where = self.positions.attribute(node, attribute)
            return Problem(where, self.attribute_message(tag, attribute, said, spec))
        return Problem(where, self.element_message(tag, node, said, spec))

    def attribute_message(self, tag: str, attribute: str, said: str, spec: _Element) -> str:
        if "is not allowed" in said:
            close = difflib.get_close_matches(attribute, spec.attributes, n=1)
            hint = f"did you mean {close[0]}? " if close else ""
            known = ", ".join(spec.attributes) or "none"
            return f"<{tag}> has no attribute {attribute!r} ({hint}its attributes: {known})"
        value = _VALUE.search(said)
        wanted = _TYPE_WORDS.get(spec.attributes.get(attribute, ""), "a valid value")
        given = f", not {next(v for v in value.groups() if v is not None)!r}" if value else ""
        return f"{attribute} of <{tag}> must be {wanted}{given}"

    def element_message(self, tag: str, node: etree._Element | None, said: str, spec: _Element) -> str:
        parent = node.getparent() if node is not None else None
        parent_tag = parent.tag if parent is not None and isinstance(parent.tag, str) else None
        required = _REQUIRED.search(said)
        if required:
            name = required.group(1)
            return f'<{tag}> needs {name}="..." ({_TYPE_WORDS.get(spec.attributes.get(name, ""), "a value")})'
        if "This element is not expected" in said and parent_tag is not None:
            around = self.elements.get(parent_tag, _Element())
            if tag in around.children and around.ordered:
                order = _tags(around.children)
                return f"<{tag}> is out of order in <{parent_tag}>: its elements come in the order {order}"
            allowed = _tags(around.children) if around.children else "no elements"
            return f"<{tag}> is not allowed in <{parent_tag}> (allowed there: {allowed})"
        if "Missing child element" in said:
            missing = [
                c for c in spec.required_children if node is None or node.find(c) is None
            ] or spec.required_children
            one = "one of " if not spec.ordered and len(missing) > 1 else ""
            return f"<{tag}> needs {one}{_tags(missing)}"
        if "Character content other than whitespace" in said:
            return f"<{tag}> holds elements ({_tags(spec.children)}), not text: remove the text or put it in a <note>"
        if "Element content is not allowed" in said:
            return f"<{tag}> holds only text: remove the elements inside it"
        return f"<{tag}>: {said}"


def validate(tree: etree._ElementTree, positions: Positions) -> list[Problem]:
    """Schema errors of a parsed procedure (empty when it conforms), one per problem."""
    root = tree.getroot()
    if root.tag != ROOT:
        local = etree.QName(root).localname if isinstance(root.tag, str) else str(root.tag)
        found = f"<{local}> in namespace {etree.QName(root).namespace}" if local == ROOT else f"<{local}>"
        return [Problem(positions.element(root), f"the root element must be <{ROOT}> (with no namespace), not {found}")]
    schema = _schema()
    with _validation_lock:
        if schema.validate(tree):
            return []
        entries = list(cast(Iterable[etree._LogEntry], schema.error_log))  # lxml-stubs: not iterable
    rewriter = _Rewriter(tree, positions)
    return sorted(dict.fromkeys(rewriter.problem(entry) for entry in entries))
