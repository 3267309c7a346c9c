"""YAML text to :class:`~datafile.nodes.Node` trees, refusing what a data file never needs.

Built from PyYAML's event stream (libyaml when available) rather than its composer and
constructor, so that:

- an alias (``*name``) is refused where it is written: expanding aliases is how a few hundred
  bytes become gigabytes (the "billion laughs"), and no Caretaker file needs them;
- only the safe schema's scalars exist (string, integer, real, boolean, null); any other tag
  (``!!python/object``, ``!!binary``, ``!custom``) is refused; timestamps stay strings;
- a repeated key is an error (YAML keeps the last one silently) and keys must be strings;
- nesting is limited and the tree is built without recursion, so no input ends in a
  ``RecursionError``; an integer too long to convert is an error, not a ``ValueError``.
"""

from __future__ import annotations

from typing import Any

import yaml
from yaml.constructor import SafeConstructor
from yaml.resolver import Resolver

from datafile.errors import DataFileError
from datafile.nodes import MAPPING, SCALAR, SEQUENCE, Node, Scalar

__all__ = ["MAX_DEPTH", "parse_yaml"]

#: Deeper nesting than this is refused (no Caretaker file nests more than ~8 levels).
MAX_DEPTH = 64

_Loader: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)
_TAG = "tag:yaml.org,2002:"
_resolver = Resolver()
_constructor = SafeConstructor()
_CONSTRUCT = {
    _TAG + "int": _constructor.construct_yaml_int,
    _TAG + "float": _constructor.construct_yaml_float,
    _TAG + "bool": _constructor.construct_yaml_bool,
    _TAG + "null": _constructor.construct_yaml_null,
}
#: Implicitly resolved tags whose text is kept as a string.
_AS_TEXT = {_TAG + "str", _TAG + "timestamp", _TAG + "merge", _TAG + "value"}


class _Open:
    """A mapping or sequence being built: its start, its items so far, a key awaiting its value."""

    __slots__ = ("kind", "line", "column", "items", "key", "key_line", "keys")

    def __init__(self, kind: str, line: int, column: int) -> None:
        self.kind = kind
        self.line = line
        self.column = column
        self.items: list[Any] = []
        self.key: str | None = None
        self.key_line = 0
        self.keys: set[str] = set()


def _shorten(text: str) -> str:
    return repr(text) if len(text) <= 24 else f"{text[:20]!r}... ({len(text)} characters)"


def _line(event: Any) -> int:
    mark = getattr(event, "start_mark", None)
    return mark.line + 1 if mark is not None else 0


def _column(event: Any) -> int:
    mark = getattr(event, "start_mark", None)
    return mark.column + 1 if mark is not None else 0


def _scalar(event: Any, path: str) -> Scalar:
    tag = event.tag
    if tag in (None, "!"):
        tag = _resolver.resolve(yaml.ScalarNode, event.value, event.implicit) if tag is None else _TAG + "str"  # type: ignore[no-untyped-call]
    if tag in _AS_TEXT:
        return str(event.value)
    construct = _CONSTRUCT.get(tag)
    if construct is None:
        raise DataFileError(
            path,
            _line(event),
            "",
            f"the YAML tag {tag!r} is not allowed here (plain values only: text, numbers, true/false)",
        )
    try:
        value: Scalar = construct(yaml.ScalarNode(tag, event.value))
    except ValueError:  # an integer of thousands of digits, a malformed explicit !!int
        raise DataFileError(path, _line(event), "", f"{_shorten(event.value)} is not a usable number") from None
    return value


def parse_yaml(text: str, path: str) -> Node:
    """The single document of ``text`` as a Node tree (an empty file is a null scalar on line 1).

    Raises:
        DataFileError: not valid YAML (with the line), an alias, a disallowed tag, a repeated or
            non-string key, more than one document, nesting deeper than :data:`MAX_DEPTH`.
    """
    loader = _Loader(text)
    root: Node | None = None
    stack: list[_Open] = []
    documents = 0
    try:
        while loader.check_event():
            event = loader.get_event()
            if isinstance(event, yaml.DocumentStartEvent):
                documents += 1
                if documents > 1:
                    raise DataFileError(
                        path, _line(event), "", "more than one YAML document (---); a data file holds one"
                    )
                continue
            if isinstance(event, yaml.AliasEvent):
                raise DataFileError(
                    path, _line(event), "", f"YAML aliases (*{event.anchor}) are not allowed; write the value out"
                )
            node: Node | None = None
            if isinstance(event, yaml.ScalarEvent):
                node = Node(SCALAR, _scalar(event, path), _line(event), _column(event))
            elif isinstance(event, (yaml.MappingStartEvent, yaml.SequenceStartEvent)):
                if event.tag not in (None, "!", _TAG + "map", _TAG + "seq"):
                    raise DataFileError(path, _line(event), "", f"the YAML tag {event.tag!r} is not allowed here")
                if len(stack) >= MAX_DEPTH:
                    raise DataFileError(path, _line(event), "", f"nested deeper than {MAX_DEPTH} levels")
                kind = MAPPING if isinstance(event, yaml.MappingStartEvent) else SEQUENCE
                if stack and stack[-1].kind == MAPPING and stack[-1].key is None:
                    raise DataFileError(path, _line(event), "", "a key must be plain text, not a list or mapping")
                stack.append(_Open(kind, _line(event), _column(event)))
                continue
            elif isinstance(event, (yaml.MappingEndEvent, yaml.SequenceEndEvent)):
                done = stack.pop()
                node = Node(MAPPING if done.kind == MAPPING else SEQUENCE, tuple(done.items), done.line, done.column)
            else:
                continue  # stream and document boundaries
            if not stack:
                root = node
                continue
            parent = stack[-1]
            if parent.kind == SEQUENCE:
                parent.items.append(node)
            elif parent.key is None:
                if not isinstance(node.value, str):
                    raise DataFileError(path, node.line, "", f"keys must be text, got {node.describe()} (quote it)")
                if node.value in parent.keys:
                    raise DataFileError(path, node.line, "", f"duplicate key {node.value!r}")
                parent.keys.add(node.value)
                parent.key, parent.key_line = node.value, node.line
            else:
                parent.items.append((parent.key, parent.key_line, node))
                parent.key = None
    except yaml.MarkedYAMLError as exc:
        mark = exc.problem_mark or exc.context_mark
        problem = exc.problem or exc.context or "syntax error"
        raise DataFileError(path, mark.line + 1 if mark else 0, "", f"not valid YAML: {problem}") from None
    except yaml.reader.ReaderError as exc:
        line = text.count("\n", 0, max(0, exc.position)) + 1
        code = exc.character if isinstance(exc.character, int) else ord(str(exc.character)[:1] or "\0")
        raise DataFileError(
            path, line, "", f"not valid YAML: character U+{code:04X} is not allowed ({exc.reason})"
        ) from None
    except yaml.YAMLError as exc:
        raise DataFileError(path, 0, "", f"not valid YAML: {' '.join(str(exc).split())}") from None
    finally:
        loader.dispose()
    return root if root is not None else Node(SCALAR, None, 1, 1)
