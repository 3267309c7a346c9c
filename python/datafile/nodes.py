"""The parsed form of a data file: values with the line and column they were written on.

YAML and JSON files both parse into :class:`Node` trees, so every loader checks them the same
way and every error can name its line.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Literal

__all__ = ["Node", "Scalar", "MAPPING", "SEQUENCE", "SCALAR"]

#: A scalar's value: what YAML's safe schema and JSON can express.
Scalar = str | int | float | bool | None

MAPPING: Literal["mapping"] = "mapping"
SEQUENCE: Literal["sequence"] = "sequence"
SCALAR: Literal["scalar"] = "scalar"


@dataclass(frozen=True)
class Node:
    """One value of a data file.

    ``value`` is, by ``kind``: a tuple of ``(key, key_line, Node)`` for a mapping (keys are
    always strings, never repeated: the parsers refuse both), a tuple of Nodes for a sequence,
    or the Python value of a scalar.
    """

    kind: Literal["mapping", "sequence", "scalar"]
    value: Any
    line: int
    column: int = 0

    @property
    def entries(self) -> tuple[tuple[str, int, Node], ...]:
        """The ``(key, key_line, value)`` entries of a mapping (empty for anything else)."""
        return self.value if self.kind == MAPPING else ()

    @property
    def items(self) -> tuple[Node, ...]:
        """The items of a sequence (empty for anything else)."""
        return self.value if self.kind == SEQUENCE else ()

    def plain(self) -> Any:
        """The value as plain Python data (dict, list, scalars), for code that needs no lines."""
        if self.kind == MAPPING:
            return {key: node.plain() for key, _, node in self.value}
        if self.kind == SEQUENCE:
            return [node.plain() for node in self.value]
        return self.value

    def describe(self) -> str:
        """What the value is, for messages: ``a mapping``, ``a list of 3 items``, ``int 5``."""
        if self.kind == MAPPING:
            return "a mapping"
        if self.kind == SEQUENCE:
            return f"a list of {len(self.value)} items"
        if self.value is None:
            return "nothing"
        text = repr(self.value)
        if len(text) > 60:
            text = text[:57] + "..."
        return f"{type(self.value).__name__} {text}"
