"""Typed, located access to a parsed data file: every check that fails names file, line and key.

A loader walks its file with :class:`Field`::

    root = load_file(path)
    robot = root.mapping(required=("name", "urdf"), optional=("base",))
    name = robot["name"].text()
    urdf = robot["urdf"].file_path()          # relative to the file that names it
    base = robot.get("base")                  # None when absent

and gets, for any mistake, one :class:`~datafile.errors.DataFileError` line such as
``iva.yaml:12: robot.base.xyz: expected a list of 3 numbers, got a list of 2 items``.
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path
from typing import Any

from datafile.errors import DataFileError
from datafile.nodes import MAPPING, SCALAR, SEQUENCE, Node

__all__ = ["Field"]


class Field:
    """One value of a data file together with where it is: the file, its line, its key path.

    ``error`` is the exception type raised (a :class:`DataFileError` subclass taking the same
    arguments), so each kind of file keeps its own named error.
    """

    __slots__ = ("node", "path", "key", "error")

    def __init__(self, node: Node, path: Path, key: str = "", error: type[DataFileError] = DataFileError) -> None:
        self.node = node
        self.path = path
        self.key = key
        self.error = error

    # --- where ---------------------------------------------------------------------------

    @property
    def line(self) -> int:
        return self.node.line

    @property
    def folder(self) -> Path:
        """The folder of the file: relative paths in the file are relative to it."""
        return self.path.parent

    def fail(self, problem: str, *, line: int | None = None, key: str | None = None) -> DataFileError:
        """The error for this value (or for ``key`` on ``line``): raise it."""
        return self.error(self.path, self.line if line is None else line, self.key if key is None else key, problem)

    def _child(self, node: Node, name: str) -> Field:
        return Field(node, self.path, self._key_of(name), self.error)

    def _item(self, node: Node, index: int) -> Field:
        return Field(node, self.path, f"{self.key}[{index}]", self.error)

    def describe(self) -> str:
        return self.node.describe()

    def plain(self) -> Any:
        """The value as plain Python data, unchecked (for pass-through sections)."""
        return self.node.plain()

    # --- mappings ------------------------------------------------------------------------

    def mapping(self, *, required: Iterable[str] = (), optional: Iterable[str] = (), any_keys: bool = False) -> Field:
        """Check this is a mapping with every ``required`` key and (unless ``any_keys``) no key
        outside ``required`` and ``optional``; return self for chaining."""
        if self.node.kind != MAPPING:
            raise self.fail(f"expected a mapping, got {self.describe()}")
        required = tuple(required)
        allowed = set(required) | set(optional)
        if not any_keys:
            for name, line, _ in self.node.entries:
                if name not in allowed:
                    raise self.fail(
                        f"unknown key {name!r} (allowed: {', '.join(sorted(allowed)) or 'none'})",
                        line=line,
                        key=self._key_of(name),
                    )
        present = {name for name, _, _ in self.node.entries}
        for name in required:
            if name not in present:
                raise self.fail("missing required key", key=self._key_of(name))
        return self

    def _key_of(self, name: str) -> str:
        return f"{self.key}.{name}" if self.key else name

    def has(self, name: str) -> bool:
        return any(key == name for key, _, _ in self.node.entries)

    def get(self, name: str) -> Field | None:
        """The value of key ``name``, or None when it is absent (a written ``null`` is a value)."""
        for key, _, node in self.node.entries:
            if key == name:
                return self._child(node, name)
        return None

    def __getitem__(self, name: str) -> Field:
        found = self.get(name)
        if found is None:
            raise self.fail("missing required key", key=self._key_of(name))
        return found

    def entries(self) -> list[tuple[str, Field]]:
        """``(key, value)`` of a mapping in file order (checks that it is one)."""
        self.mapping(any_keys=True)
        return [(key, self._child(node, key)) for key, _, node in self.node.entries]

    # --- sequences -----------------------------------------------------------------------

    def sequence(self, *, min_items: int = 0, max_items: int | None = None) -> list[Field]:
        if self.node.kind != SEQUENCE:
            raise self.fail(f"expected a list, got {self.describe()}")
        count = len(self.node.items)
        if count < min_items:
            raise self.fail(f"expected at least {min_items} item{'s' if min_items != 1 else ''}, got {count}")
        if max_items is not None and count > max_items:
            raise self.fail(f"expected at most {max_items} items, got {count}")
        return [self._item(node, i) for i, node in enumerate(self.node.items)]

    def numbers(self, count: int, *, min: float | None = None, max: float | None = None) -> tuple[float, ...]:
        """Exactly ``count`` finite numbers."""
        if self.node.kind != SEQUENCE or len(self.node.items) != count:
            raise self.fail(f"expected a list of {count} numbers, got {self.describe()}")
        return tuple(item.number(min=min, max=max) for item in self.sequence())

    def names(self, *, min_items: int = 0, unique: bool = True) -> tuple[str, ...]:
        """A list of non-empty texts (joint names, link names)."""
        items = self.sequence(min_items=min_items)
        names = tuple(item.text() for item in items)
        if unique:
            for i, name in enumerate(names):
                if name in names[:i]:
                    raise items[i].fail(f"{name!r} is listed twice")
        return names

    # --- scalars -------------------------------------------------------------------------

    def _scalar(self) -> Any:
        if self.node.kind != SCALAR:
            return ...
        return self.node.value

    def text(self, *, empty: bool = False) -> str:
        value = self._scalar()
        if not isinstance(value, str):
            raise self.fail(f"expected text, got {self.describe()}")
        if not empty and not value:
            raise self.fail("must not be empty")
        return value

    def choice(self, options: Sequence[str]) -> str:
        value = self.text()
        if value not in options:
            raise self.fail(f"unknown value {value!r}; expected one of {', '.join(options)}")
        return value

    def boolean(self) -> bool:
        value = self._scalar()
        if not isinstance(value, bool):
            raise self.fail(f"expected true or false, got {self.describe()}")
        return value

    def integer(self, *, min: int | None = None, max: int | None = None) -> int:
        value = self._scalar()
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.fail(f"expected an integer, got {self.describe()}")
        self._check_range(value, min, max)
        return value

    def number(self, *, min: float | None = None, max: float | None = None) -> float:
        value = self._scalar()
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(f"expected a number, got {self.describe()}")
        try:
            converted = float(value)
        except OverflowError:
            converted = math.inf
        if not math.isfinite(converted):
            raise self.fail(f"expected a finite number, got {self.describe()}")
        self._check_range(converted, min, max)
        return converted

    def _check_range(self, value: float, minimum: float | None, maximum: float | None) -> None:
        if minimum is not None and value < minimum:
            raise self.fail(f"{value!r} is below the minimum {minimum!r}")
        if maximum is not None and value > maximum:
            raise self.fail(f"{value!r} is above the maximum {maximum!r}")

    def file_path(
        self, *, folder: bool = False, must_exist: bool = True, shipped: Path | None = None, what: str = ""
    ) -> Path:
        """A path written in the file, relative to the file's folder (``~`` expanded).

        ``must_exist`` checks it is there and of the right kind (file or ``folder``).
        ``shipped``: a folder of shipped YAML files that a bare name (``iva``: no folder, no
        suffix, and no such file beside this one) names, so a file kept outside the checkout
        names shipped ones without the checkout's path; ``what`` they are, for the message.
        """
        text = self.text()
        if "\x00" in text:
            raise self.fail("a path must not contain NUL characters")
        path = Path(os.path.abspath(self.folder / Path(text).expanduser()))
        bare = "/" not in text and not Path(text).suffix and not text.startswith("~")
        if shipped is not None and bare and not path.exists():
            candidate = shipped / f"{text}.yaml"
            if not candidate.is_file():
                known = ", ".join(sorted(p.stem for p in shipped.glob("*.yaml")))
                raise self.fail(f"no shipped {what or 'file'} named {text!r}; give a file path or one of: {known}")
            return candidate
        if must_exist:
            kind = "folder" if folder else "file"
            try:
                ok = path.is_dir() if folder else path.is_file()
            except OSError as exc:
                raise self.fail(f"cannot use {kind} {path}: {exc.strerror}") from None
            if not ok:
                raise self.fail(f"no such {kind}: {path} ({text!r} relative to {self.folder})")
        return path
