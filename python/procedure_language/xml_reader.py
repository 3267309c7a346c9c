"""Reading a procedure file from outside: bytes → XML tree, or one problem that says what to fix.

A procedure file is hostile until checked. It must be UTF-8; it may not have a DOCTYPE, so no DTD
and no entity is ever read or expanded (checked on the text before the XML parser sees it, and
the parser is also told to load, resolve and fetch nothing). Syntax errors are reported where an
author must look: an unclosed element at the line that opens it, a bad byte at its line and
column. Only the first error is reported: after it, a parser's messages are guesses.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import cast

from lxml import etree

from procedure_language.diagnostics import Problem
from procedure_language.model import Location

__all__ = ["MAX_BYTES", "Positions", "Source", "read_xml"]

#: Procedures are a few kilobytes; a larger file is refused before it is parsed.
MAX_BYTES = 4 * 1024 * 1024

_BOM = b"\xef\xbb\xbf"
_DECLARED_ENCODING = re.compile(r"""\A<\?xml[^>]*?\bencoding\s*=\s*["']([^"']*)["']""")
# Comments, CDATA sections and processing instructions may mention "<!DOCTYPE" harmlessly.
_INERT = re.compile(r"<!--.*?-->|<!\[CDATA\[.*?\]\]>|<\?.*?\?>", re.DOTALL)
_DECLARATION = re.compile(r"<!(DOCTYPE|ENTITY|ELEMENT|ATTLIST|NOTATION)\b")
_PREMATURE = re.compile(r"Premature end of data in tag (\S+) line (\d+)")
_MISMATCH = re.compile(r"Opening and ending tag mismatch: (\S+) line (\d+) and (\S+)")
_ENTITY = re.compile(r"Entity '([^']*)' not defined")


@dataclass(frozen=True)
class Source:
    """A procedure file's text, for finding where an element or attribute is written."""

    path: str
    lines: tuple[str, ...]

    def start_tag(self, line: int, tag: str, start: int = 0) -> int:
        """The column of ``<tag`` on ``line`` at or after column ``start + 1`` (1 when not found)."""
        text = self.lines[line - 1] if 0 < line <= len(self.lines) else ""
        found = text.find(f"<{tag}", start)
        return found + 1 if found >= 0 else 1

    def at(self, line: int, col: int) -> Location:
        return Location(self.path, max(line, 1), max(col, 1))


class Positions:
    """Finds the column of each element's start tag and of its attributes in the source text."""

    def __init__(self, source: Source) -> None:
        self.source = source
        self._next_search: dict[int, int] = {}
        self._element_col: dict[etree._Element, int] = {}

    def _line(self, number: int) -> str:
        lines = self.source.lines
        return lines[number - 1] if 0 < number <= len(lines) else ""

    def element(self, el: etree._Element) -> Location:
        line = cast(int | None, el.sourceline) or 1  # lxml-stubs mistype sourceline
        if el not in self._element_col:
            text = self._line(line)
            start = self._next_search.get(line, 0)
            found = text.find(f"<{el.tag}", start)
            self._next_search[line] = found + 1 if found >= 0 else start
            self._element_col[el] = found + 1 if found >= 0 else 1
        return Location(self.source.path, line, self._element_col[el])

    def attribute(self, el: etree._Element, name: str) -> Location:
        """Where attribute ``name`` of ``el`` is written (the element when it is absent)."""
        start = self.element(el)
        pattern = re.compile(rf"(?<![\w-]){re.escape(name)}\s*=")
        for offset in range(12):  # a start tag's attributes may span a few lines
            text = self._line(start.line + offset)
            begin = start.col - 1 if offset == 0 else 0
            match = pattern.search(text, begin)
            if match:
                return Location(self.source.path, start.line + offset, match.start() + 1)
            if ">" in text[begin:]:
                break
        return start

    def text(self, el: etree._Element) -> Location:
        """Where an element's text content starts (just after its start tag)."""
        start = self.element(el)
        end = self._line(start.line).find(">", start.col - 1)
        return Location(self.source.path, start.line, end + 2 if end >= 0 else start.col)


def _position(data: bytes, offset: int) -> tuple[int, int]:
    """Line and column (in characters, 1-based) of a byte offset in UTF-8 text."""
    line_start = data.rfind(b"\n", 0, offset) + 1
    column = len(data[line_start:offset].decode("utf-8", errors="replace")) + 1
    return data.count(b"\n", 0, offset) + 1, column


def _decode(path: str, data: bytes) -> tuple[str | None, Problem | None]:
    body = data[len(_BOM) :] if data.startswith(_BOM) else data
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        line, col = _position(body, exc.start)
        bad = body[exc.start : exc.end].hex(" ")
        return None, Problem(
            Location(path, line, col), f"not UTF-8: byte(s) {bad} cannot be read; save the file as UTF-8"
        )
    declared = _DECLARED_ENCODING.match(text)
    if declared and declared.group(1).lower().replace("_", "-") not in ("utf-8", "utf8"):
        return None, Problem(
            Location(path, 1, declared.start(1) + 1),
            f"the file declares encoding {declared.group(1)!r}; procedures are UTF-8: "
            'write encoding="UTF-8" or leave the declaration out',
        )
    if "\x00" in text:
        line, col = _position(body, body.index(b"\x00"))
        return None, Problem(Location(path, line, col), "a NUL character is not allowed in XML; remove it")
    return text, None


def _declarations(path: str, text: str) -> Problem | None:
    """A DOCTYPE or DTD declaration, refused before any parser reads it."""
    inert = _INERT.sub(lambda m: re.sub(r"[^\n]", " ", m.group(0)), text)
    found = _DECLARATION.search(inert)
    if found is None:
        return None
    line = inert.count("\n", 0, found.start()) + 1
    col = found.start() - (inert.rfind("\n", 0, found.start()) + 1) + 1
    return Problem(
        Location(path, line, col),
        f"<!{found.group(1)} ...> is not allowed in a procedure (no DTD, no "
        "entities, nothing is read from elsewhere): remove it",
    )


def _syntax_problem(source: Source, entry: etree._LogEntry) -> Problem:
    """The first syntax error, in an author's words, where the author must look."""
    message = " ".join(entry.message.split())[:300]  # libxml2 may quote a piece of the file
    unclosed = _MISMATCH.search(message) or _PREMATURE.search(message)
    if unclosed:
        tag, opened = unclosed.group(1), int(unclosed.group(2))
        why = (
            f"</{unclosed.group(3)}> at line {entry.line} comes first"
            if unclosed.re is _MISMATCH
            else "the file ends first"
        )
        return Problem(
            source.at(opened, source.start_tag(opened, tag)),
            f"<{tag}> opened here is never closed ({why}): add </{tag}> where it ends",
        )
    entity = _ENTITY.search(message)
    if entity:
        line = source.lines[entry.line - 1] if 0 < entry.line <= len(source.lines) else ""
        written = line.rfind(f"&{entity.group(1)};", 0, max(entry.column, 1))  # libxml2 points after it
        return Problem(
            source.at(entry.line, written + 1 if written >= 0 else entry.column),
            f"&{entity.group(1)}; is an entity; procedures use none but &lt; &gt; &amp; &quot; &apos; "
            "and character references (&#...;): remove it or write the text",
        )
    return Problem(source.at(entry.line, entry.column), f"not well-formed XML: {message}")


def read_xml(path: str | Path) -> tuple[etree._ElementTree | None, Source, list[Problem]]:
    """Read and parse one procedure file: the tree, or None and the one problem that stopped it."""
    name = str(path)
    empty = Source(name, ())
    try:
        with open(path, "rb") as file:
            data = file.read(MAX_BYTES + 1)
    except OSError as exc:
        return None, empty, [Problem(Location(name, 1, 1), f"cannot read: {exc.strerror or exc}")]
    if len(data) > MAX_BYTES:
        return (
            None,
            empty,
            [Problem(Location(name, 1, 1), f"larger than {MAX_BYTES // (1024 * 1024)} MiB: not a procedure file")],
        )
    text, problem = _decode(name, data)
    if text is None:
        return None, empty, [problem] if problem else []
    source = Source(name, tuple(text.splitlines()))
    problem = _declarations(name, text)
    if problem is not None:
        return None, source, [problem]
    parser = etree.XMLParser(
        resolve_entities=False,
        no_network=True,
        load_dtd=False,
        dtd_validation=False,
        huge_tree=False,
        remove_blank_text=False,
    )
    try:
        root = etree.fromstring(text.encode("utf-8"), parser)
    except etree.XMLSyntaxError as exc:
        entries = list(cast(Iterable[etree._LogEntry], parser.error_log))
        if entries:
            return None, source, [_syntax_problem(source, entries[0])]
        line, col = exc.position
        return None, source, [Problem(source.at(line, col), f"not well-formed XML: {exc.msg}")]
    return root.getroottree(), source, []
