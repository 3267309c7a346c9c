"""System Representation (SysRep) files: the commands and telemetry a procedure may name.

A SysRep is the contract between procedure authors and the systems that carry procedures out
(docs/architecture.md, interface 1). The file form is the paper's Fig. 1::

    id: affordance_templates
    name: CRAFTSMAN AffordanceTemplates YAML
    commands:
    - [add_affordance_template, Add Affordance Template,
       [[affordance_template, string], [hide_waypoints, boolean]]]
    telemetry:
    - [robot_active, Robot Active, boolean]

Optional extensions never change that form; they ride in a trailing mapping:

- command: ``[id, label, args, {hazardous: true, description: "..."}]``
- argument: ``[name, type, {units: m, min: 0, max: 1, enum: [...], description: "..."}]``
- telemetry: ``[id, label, type, {units: ..., min: ..., max: ..., enum: [...], description: ...,
  limits: {...}}]`` (limits: :mod:`procedure_language.limits`)
- top level: ``description``, ``version``.

Every error is one line, ``file:line: where: problem``, naming the entry and what to fix. The
Java loader (java/pax-plugins) produces the same messages; both are checked against the shared
fixtures in tests/fixtures/sysrep. The file is read by the shared :mod:`datafile` reader, so a
hostile file (an alias bomb, a tag, bad bytes, deep nesting) is refused the same way as every
other data file.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from datafile import DataFileError, Node, load_file
from datafile.nodes import MAPPING, SCALAR, SEQUENCE
from procedure_language.limits import Limits, parse_limits

__all__ = [
    "TYPES",
    "Argument",
    "Command",
    "SysRep",
    "SysRepError",
    "Telemetry",
    "load_sysrep",
    "load_sysrep_dir",
]

#: The four SysRep value types and the Python type each maps to.
TYPES: dict[str, type] = {"string": str, "boolean": bool, "integer": int, "real": float}

_IDENTIFIER = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")
_TOP_LEVEL_KEYS = {"id", "name", "commands", "telemetry", "description", "version"}
_VALUE_EXTENSIONS = {"units", "min", "max", "enum", "description"}
_COMMAND_EXTENSIONS = {"hazardous", "description"}


class SysRepError(DataFileError):
    """A SysRep file is malformed. ``str(err)`` is ``file:line: where: problem``."""

    @property
    def where(self) -> str:
        """The entry the problem is in (``commands[0] 'go' argument 1``): the error's key."""
        return self.key


@dataclass(frozen=True)
class Argument:
    """A typed argument of a command, with optional limits for validation and forms."""

    name: str
    type: str
    units: str | None = None
    min: float | None = None
    max: float | None = None
    enum: tuple[Any, ...] | None = None
    description: str | None = None

    def check(self, value: Any) -> Any:
        """Return ``value`` converted to this argument's type, or raise ValueError saying why."""
        return check_value(self.name, self.type, value, self.min, self.max, self.enum)


@dataclass(frozen=True)
class Command:
    """A command of a system: what a procedure's command instruction sends."""

    id: str
    label: str
    args: tuple[Argument, ...]
    hazardous: bool = False
    description: str | None = None
    line: int = 0

    def arg(self, name: str) -> Argument | None:
        """The argument called ``name``, or None."""
        return next((a for a in self.args if a.name == name), None)


@dataclass(frozen=True)
class Telemetry:
    """A telemetry item of a system: what a verify or wait instruction reads."""

    id: str
    label: str
    type: str
    units: str | None = None
    min: float | None = None
    max: float | None = None
    enum: tuple[Any, ...] | None = None
    description: str | None = None
    limits: Limits | None = None  # what a monitor with limit="red" (and the console's colours) reads
    line: int = 0


@dataclass(frozen=True)
class SysRep:
    """One loaded SysRep file."""

    id: str
    name: str
    commands: tuple[Command, ...]
    telemetry: tuple[Telemetry, ...]
    path: str = ""
    description: str | None = None
    version: str | None = None

    def command(self, command_id: str) -> Command | None:
        """The command with ``command_id``, or None."""
        return next((c for c in self.commands if c.id == command_id), None)

    def telemetry_item(self, item_id: str) -> Telemetry | None:
        """The telemetry item with ``item_id``, or None."""
        return next((t for t in self.telemetry if t.id == item_id), None)


def check_value(
    name: str,
    type_name: str,
    value: Any,
    minimum: float | None = None,
    maximum: float | None = None,
    enum: tuple[Any, ...] | None = None,
) -> Any:
    """Convert ``value`` to SysRep type ``type_name``; raise ValueError naming ``name`` if it can't.

    Strings are accepted for every type (operators type them), so "3" is a valid integer and
    "true"/"false" valid booleans; a bool is never taken as a number.
    """
    if type_name not in TYPES:
        raise ValueError(f"{name}: unknown type {type_name!r} (expected one of {', '.join(TYPES)})")
    converted: Any
    if type_name == "string":
        if not isinstance(value, str):
            raise ValueError(f"{name}: expected string, got {type(value).__name__} {value!r}")
        converted = value
    elif type_name == "boolean":
        if isinstance(value, bool):
            converted = value
        elif isinstance(value, str) and value.strip().lower() in ("true", "false"):
            converted = value.strip().lower() == "true"
        else:
            raise ValueError(f"{name}: expected boolean (true/false), got {value!r}")
    elif type_name == "integer":
        if isinstance(value, bool) or isinstance(value, float) and not value.is_integer():
            raise ValueError(f"{name}: expected integer, got {value!r}")
        try:
            converted = int(value.strip()) if isinstance(value, str) else int(value)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected integer, got {value!r}") from None
    else:
        if isinstance(value, bool):
            raise ValueError(f"{name}: expected real, got {value!r}")
        try:
            converted = float(value.strip()) if isinstance(value, str) else float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{name}: expected real, got {value!r}") from None
    if minimum is not None and converted < minimum:
        raise ValueError(f"{name}: {converted!r} is below the minimum {minimum!r}")
    if maximum is not None and converted > maximum:
        raise ValueError(f"{name}: {converted!r} is above the maximum {maximum!r}")
    if enum is not None and converted not in enum:
        raise ValueError(f"{name}: {converted!r} is not one of {list(enum)!r}")
    return converted


class _Reader:
    """Walks the file's node tree (:mod:`datafile`) so every error can name its line."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, node: Node | None, where: str, problem: str) -> SysRepError:
        return SysRepError(self.path, node.line if node is not None else 0, where, problem)

    def scalar(self, node: Node, where: str, what: str) -> str:
        if node.kind != SCALAR or not isinstance(node.value, str):
            raise self.fail(node, where, f"{what} must be a string, got {node.describe()}")
        return node.value

    def identifier(self, node: Node, where: str, what: str) -> str:
        value = self.scalar(node, where, what)
        if not _IDENTIFIER.match(value):
            raise self.fail(node, where, f"{what} {value!r} is not an identifier (letters, digits, _)")
        return value

    def type_name(self, node: Node, where: str) -> str:
        value = self.scalar(node, where, "type")
        if value not in TYPES:
            raise self.fail(node, where, f"unknown type {value!r} (expected one of {', '.join(TYPES)})")
        return value

    def extensions(self, node: Node, where: str, allowed: set[str]) -> dict[str, Any]:
        if node.kind != MAPPING:
            raise self.fail(node, where, f"extension must be a mapping, got {node.describe()}")
        data: dict[str, Any] = node.plain()
        for key in data:
            if key not in allowed:
                raise self.fail(node, where, f"unknown extension {key!r} (allowed: {', '.join(sorted(allowed))})")
        for key in ("min", "max"):
            if key in data and (
                isinstance(data[key], bool) or not isinstance(data[key], (int, float)) or not math.isfinite(data[key])
            ):
                raise self.fail(node, where, f"extension {key!r} must be a finite number, got {data[key]!r}")
        if "enum" in data and not isinstance(data["enum"], list):
            raise self.fail(node, where, f"extension 'enum' must be a list, got {data['enum']!r}")
        if "hazardous" in data and not isinstance(data["hazardous"], bool):
            raise self.fail(node, where, f"extension 'hazardous' must be true or false, got {data['hazardous']!r}")
        for key in ("units", "description"):
            if key in data and not isinstance(data[key], str):
                raise self.fail(node, where, f"extension {key!r} must be a string, got {data[key]!r}")
        return data

    def value_extensions(self, node: Node, where: str, type_name: str, *, limits: bool = False) -> dict[str, Any]:
        data = self.extensions(node, where, _VALUE_EXTENSIONS | ({"limits"} if limits else set()))
        if ("min" in data or "max" in data) and type_name not in ("integer", "real"):
            raise self.fail(node, where, f"min/max apply to integer or real, not {type_name}")
        if "enum" in data:
            try:
                data["enum"] = tuple(check_value("enum", type_name, v) for v in data["enum"])
            except (ValueError, OverflowError) as exc:
                raise self.fail(node, where, f"enum value does not match type {type_name}: {exc}") from None
        return data

    def argument(self, node: Node, where: str) -> Argument:
        if node.kind != SEQUENCE or len(node.items) not in (2, 3):
            raise self.fail(
                node, where, f"argument must be [name, type] or [name, type, {{extensions}}], got {node.describe()}"
            )
        name = self.identifier(node.items[0], where, "argument name")
        where = f"{where} {name!r}"
        type_name = self.type_name(node.items[1], where)
        ext = self.value_extensions(node.items[2], where, type_name) if len(node.items) == 3 else {}
        return Argument(name=name, type=type_name, **ext)

    def command(self, node: Node, index: int) -> Command:
        where = f"commands[{index}]"
        if node.kind != SEQUENCE or len(node.items) not in (3, 4):
            raise self.fail(
                node, where, f"command must be [id, label, [[arg, type], ...]] (3 or 4 items), got {node.describe()}"
            )
        command_id = self.identifier(node.items[0], where, "command id")
        where = f"{where} {command_id!r}"
        label = self.scalar(node.items[1], where, "label")
        args_node = node.items[2]
        if args_node.kind != SEQUENCE:
            raise self.fail(args_node, where, f"arguments must be a list of [name, type], got {args_node.describe()}")
        args: list[Argument] = []
        for i, arg_node in enumerate(args_node.items):
            arg = self.argument(arg_node, f"{where} argument {i + 1}")
            if any(a.name == arg.name for a in args):
                raise self.fail(arg_node, where, f"duplicate argument {arg.name!r}")
            args.append(arg)
        ext = self.extensions(node.items[3], where, _COMMAND_EXTENSIONS) if len(node.items) == 4 else {}
        return Command(command_id, label, tuple(args), line=node.line, **ext)

    def telemetry(self, node: Node, index: int) -> Telemetry:
        where = f"telemetry[{index}]"
        if node.kind != SEQUENCE or len(node.items) not in (3, 4):
            raise self.fail(node, where, f"telemetry must be [id, label, type] (3 or 4 items), got {node.describe()}")
        item_id = self.identifier(node.items[0], where, "telemetry id")
        where = f"{where} {item_id!r}"
        label = self.scalar(node.items[1], where, "label")
        type_name = self.type_name(node.items[2], where)
        ext = self.value_extensions(node.items[3], where, type_name, limits=True) if len(node.items) == 4 else {}
        if "limits" in ext:
            try:
                ext["limits"] = parse_limits(ext["limits"], type_name, lambda v: check_value("equals", type_name, v))
            except ValueError as exc:
                raise self.fail(node.items[3], where, str(exc)) from None
        return Telemetry(item_id, label, type_name, line=node.line, **ext)

    def sysrep(self, root: Node) -> SysRep:
        if root.kind != MAPPING:
            raise self.fail(
                root, "", f"a SysRep must be a mapping with id, name, commands, telemetry; got {root.describe()}"
            )
        fields: dict[str, Node] = {}
        for key, key_line, value_node in root.entries:
            if key not in _TOP_LEVEL_KEYS:
                raise SysRepError(
                    self.path, key_line, "", f"unknown key {key!r} (allowed: {', '.join(sorted(_TOP_LEVEL_KEYS))})"
                )
            fields[key] = value_node
        for required in ("id", "name"):
            if required not in fields:
                raise self.fail(root, "", f"missing required key {required!r}")
        sysrep_id = self.identifier(fields["id"], "id", "id")
        name = self.scalar(fields["name"], "name", "name")
        commands = self._entries(fields.get("commands"), "commands", self.command)
        telemetry = self._entries(fields.get("telemetry"), "telemetry", self.telemetry)
        description = (
            self.scalar(fields["description"], "description", "description") if "description" in fields else None
        )
        version = self.scalar(fields["version"], "version", "version") if "version" in fields else None
        return SysRep(sysrep_id, name, tuple(commands), tuple(telemetry), str(self.path), description, version)

    def _entries(self, node: Node | None, section: str, read: Any) -> list[Any]:
        if node is None or node.kind == SCALAR and node.value is None:
            return []
        if node.kind != SEQUENCE:
            raise self.fail(node, section, f"{section} must be a list, got {node.describe()}")
        entries: list[Any] = []
        for index, entry_node in enumerate(node.items):
            entry = read(entry_node, index)
            if any(e.id == entry.id for e in entries):
                raise self.fail(entry_node, f"{section}[{index}] {entry.id!r}", f"duplicate id {entry.id!r}")
            entries.append(entry)
        return entries


def load_sysrep(path: str | Path) -> SysRep:
    """Load and validate one SysRep file.

    Raises:
        SysRepError: the file is missing, not YAML, or not a valid SysRep; the message names
            the file, the line, the entry and what is wrong.
    """
    path = Path(path)
    root = load_file(path, error=SysRepError, json=False)
    return _Reader(path).sysrep(root.node)


def load_sysrep_dir(directory: str | Path) -> dict[str, SysRep]:
    """Load every ``*.yaml`` directly in ``directory`` (not subfolders), keyed by SysRep id.

    Raises:
        SysRepError: a file is invalid, or two files declare the same id.
    """
    sysreps: dict[str, SysRep] = {}
    for path in sorted(Path(directory).glob("*.yaml")):
        sysrep = load_sysrep(path)
        if sysrep.id in sysreps:
            raise SysRepError(path, 0, "id", f"duplicate SysRep id {sysrep.id!r} (also in {sysreps[sysrep.id].path})")
        sysreps[sysrep.id] = sysrep
    return sysreps
