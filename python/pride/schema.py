"""Structural validation of procedure XML against ``procedures/schema/procedure.xsd`` (lxml).

libxml2's messages name the schema machinery ("Element 'x', attribute 'y': ..."); they are kept
because they say exactly which element and attribute is wrong, with the element's line.
"""

from __future__ import annotations

import threading
from functools import lru_cache
from pathlib import Path

from lxml import etree

from pride.diagnostics import Problem
from pride.model import Location

__all__ = ["SCHEMA_PATH", "parse_xml", "validate"]

SCHEMA_PATH = Path(__file__).resolve().parents[2] / "procedures" / "schema" / "procedure.xsd"
_validation_lock = threading.Lock()  # one XMLSchema and its error_log are shared: validate one file at a time


@lru_cache(maxsize=1)
def _schema() -> etree.XMLSchema:
    return etree.XMLSchema(etree.parse(str(SCHEMA_PATH)))


def parse_xml(path: Path) -> tuple[etree._ElementTree | None, list[Problem]]:
    """Parse a file; on malformed XML return no tree and the syntax errors."""
    parser = etree.XMLParser(remove_blank_text=False, resolve_entities=False, no_network=True)
    try:
        return etree.parse(str(path), parser), []
    except OSError as exc:
        return None, [Problem(Location(str(path), 0, 0), f"cannot read: {exc}")]
    except etree.XMLSyntaxError as exc:
        entries = list(exc.error_log) or []
        if not entries:
            line, col = exc.position
            return None, [Problem(Location(str(path), line, col), f"not well-formed XML: {exc.msg}")]
        return None, [
            Problem(Location(str(path), e.line, max(e.column, 1)), f"not well-formed XML: {e.message}") for e in entries
        ]


def validate(path: Path, tree: etree._ElementTree, source_lines: list[str]) -> list[Problem]:
    """Schema errors of a parsed procedure (empty when it conforms)."""
    schema = _schema()
    with _validation_lock:
        if schema.validate(tree):
            return []
        entries = list(schema.error_log)
    problems = []
    for entry in entries:
        col = entry.column
        if col <= 0 and 0 < entry.line <= len(source_lines):
            col = source_lines[entry.line - 1].find("<") + 1
        problems.append(Problem(Location(str(path), entry.line, max(col, 1)), entry.message))
    return problems
