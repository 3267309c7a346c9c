"""JSON text to :class:`~datafile.nodes.Node` trees, strictly (RFC 8259) and with line numbers.

Python's ``json`` module gives values but not where they were written, accepts ``NaN`` and
``Infinity``, keeps the last of repeated keys silently and can end in ``RecursionError``. This
small parser keeps every value's line and column and refuses all of those with one message.
"""

from __future__ import annotations

import re

from datafile.errors import DataFileError
from datafile.nodes import MAPPING, SCALAR, SEQUENCE, Node, Scalar

__all__ = ["MAX_DEPTH", "parse_json"]

#: Deeper nesting than this is refused (an AT template nests 7 levels).
MAX_DEPTH = 64

_NUMBER = re.compile(r"-?(?:0|[1-9][0-9]*)(\.[0-9]+)?([eE][-+]?[0-9]+)?")
_WHITESPACE = re.compile(r"[ \t\n\r]*")
_PLAIN = re.compile(r'[^"\\\x00-\x1f]*')
_ESCAPES = {'"': '"', "\\": "\\", "/": "/", "b": "\b", "f": "\f", "n": "\n", "r": "\r", "t": "\t"}
_LITERALS: dict[str, Scalar] = {"true": True, "false": False, "null": None}


class _Parser:
    def __init__(self, text: str, path: str) -> None:
        self.text = text
        self.path = path
        self.pos = 0
        # The line of the last position asked for: positions mostly grow, so lines are counted
        # from there, not from the start (which would make a large file quadratic).
        self._mark = (0, 1)

    def where(self, pos: int) -> tuple[int, int]:
        mark_pos, mark_line = self._mark if pos >= self._mark[0] else (0, 1)
        line = mark_line + self.text.count("\n", mark_pos, pos)
        self._mark = (pos, line)
        return line, pos - (self.text.rfind("\n", 0, pos) + 1) + 1

    def fail(self, pos: int, problem: str) -> DataFileError:
        line, column = self.where(pos)
        return DataFileError(self.path, line, "", f"not valid JSON: {problem}", column=column)

    def skip(self) -> None:
        self.pos = _WHITESPACE.match(self.text, self.pos).end()  # type: ignore[union-attr]

    def peek_text(self) -> str:
        return repr(self.text[self.pos : self.pos + 12]) if self.pos < len(self.text) else "the end of the file"

    def value(self, depth: int) -> Node:
        self.skip()
        start = self.pos
        line, column = self.where(start)
        char = self.text[start : start + 1]
        if char in ("{", "["):
            if depth >= MAX_DEPTH:
                raise self.fail(start, f"nested deeper than {MAX_DEPTH} levels")
            return self.mapping(depth + 1, line, column) if char == "{" else self.sequence(depth + 1, line, column)
        if char == '"':
            return Node(SCALAR, self.string(), line, column)
        for word, literal in _LITERALS.items():
            if self.text.startswith(word, start):
                self.pos += len(word)
                return Node(SCALAR, literal, line, column)
        match = _NUMBER.match(self.text, start)
        if match is None or match.end() == start:
            if self.text.startswith(("NaN", "Infinity", "-Infinity"), start):
                raise self.fail(start, "NaN and Infinity are not JSON numbers")
            raise self.fail(start, f"expected a value, found {self.peek_text()}")
        self.pos = match.end()
        literal_text = match.group(0)
        number: Scalar
        try:
            number = float(literal_text) if match.group(1) or match.group(2) else int(literal_text)
        except ValueError:  # thousands of digits
            raise self.fail(start, f"number {literal_text[:20]}... ({len(literal_text)} digits) is too long") from None
        return Node(SCALAR, number, line, column)

    def string(self) -> str:
        start = self.pos
        self.pos += 1
        parts: list[str] = []
        while True:
            plain = _PLAIN.match(self.text, self.pos)
            assert plain is not None
            parts.append(plain.group(0))
            self.pos = plain.end()
            char = self.text[self.pos : self.pos + 1]
            if char == '"':
                self.pos += 1
                return "".join(parts)
            if char == "":
                raise self.fail(start, "string not closed before the end of the file")
            if char != "\\":
                raise self.fail(self.pos, f"control character {char!r} inside a string (write it escaped)")
            escape = self.text[self.pos + 1 : self.pos + 2]
            if escape in _ESCAPES:
                parts.append(_ESCAPES[escape])
                self.pos += 2
            elif escape == "u":
                parts.append(self.unicode_escape())
            else:
                raise self.fail(self.pos, f"invalid escape \\{escape}")

    def hex4(self, pos: int) -> int:
        digits = self.text[pos : pos + 4]
        if len(digits) != 4 or not all(c in "0123456789abcdefABCDEF" for c in digits):
            raise self.fail(pos - 2, "\\u must be followed by 4 hex digits")
        return int(digits, 16)

    def unicode_escape(self) -> str:
        start = self.pos
        code = self.hex4(self.pos + 2)
        self.pos += 6
        if 0xD800 <= code <= 0xDBFF and self.text.startswith("\\u", self.pos):
            low = self.hex4(self.pos + 2)
            if 0xDC00 <= low <= 0xDFFF:
                self.pos += 6
                return chr(0x10000 + ((code - 0xD800) << 10) + (low - 0xDC00))
        if 0xD800 <= code <= 0xDFFF:
            raise self.fail(start, "\\u escape of half a surrogate pair")
        return chr(code)

    def mapping(self, depth: int, line: int, column: int) -> Node:
        self.pos += 1
        entries: list[tuple[str, int, Node]] = []
        seen: set[str] = set()
        self.skip()
        if self.text.startswith("}", self.pos):
            self.pos += 1
            return Node(MAPPING, (), line, column)
        while True:
            self.skip()
            if not self.text.startswith('"', self.pos):
                raise self.fail(self.pos, f"expected a key in double quotes, found {self.peek_text()}")
            key_pos = self.pos
            key = self.string()
            if key in seen:
                raise self.fail(key_pos, f"duplicate key {key!r}")
            seen.add(key)
            self.skip()
            if not self.text.startswith(":", self.pos):
                raise self.fail(self.pos, f"expected ':' after key {key!r}, found {self.peek_text()}")
            self.pos += 1
            entries.append((key, self.where(key_pos)[0], self.value(depth)))
            self.skip()
            char = self.text[self.pos : self.pos + 1]
            self.pos += 1
            if char == "}":
                return Node(MAPPING, tuple(entries), line, column)
            if char != ",":
                found = self.peek_text_at(self.pos - 1)
                raise self.fail(self.pos - 1, f"expected ',' or '}}' after the value of {key!r}, found {found}")

    def sequence(self, depth: int, line: int, column: int) -> Node:
        self.pos += 1
        items: list[Node] = []
        self.skip()
        if self.text.startswith("]", self.pos):
            self.pos += 1
            return Node(SEQUENCE, (), line, column)
        while True:
            items.append(self.value(depth))
            self.skip()
            char = self.text[self.pos : self.pos + 1]
            self.pos += 1
            if char == "]":
                return Node(SEQUENCE, tuple(items), line, column)
            if char != ",":
                raise self.fail(
                    self.pos - 1,
                    f"expected ',' or ']' after item {len(items) - 1}, found {self.peek_text_at(self.pos - 1)}",
                )

    def peek_text_at(self, pos: int) -> str:
        self.pos = pos
        return self.peek_text()


def parse_json(text: str, path: str) -> Node:
    """The JSON value of ``text`` as a Node tree.

    Raises:
        DataFileError: ``file:line:column: not valid JSON: ...`` for anything RFC 8259 does not
            allow, a repeated key, or nesting deeper than :data:`MAX_DEPTH`.
    """
    parser = _Parser(text, path)
    root = parser.value(0)
    parser.skip()
    if parser.pos != len(text):
        raise parser.fail(parser.pos, f"unexpected {parser.peek_text()} after the value")
    return root
