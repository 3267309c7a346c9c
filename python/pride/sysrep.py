"""System Representation (SysRep) files: the commands and telemetry a procedure may name.

A SysRep is the contract between procedure authors and the systems that carry procedures out
(ARCHITECTURE.md, interface 1). The file form is the paper's Fig. 1::

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
- telemetry: ``[id, label, type, {units: ..., min: ..., max: ..., enum: [...], description: ...}]``
- top level: ``description``, ``version``.

Every error is one line, ``file:line: where: problem``, naming the entry and what to fix. The
Java loader (java/pax-plugins) produces the same messages; both are checked against the shared
fixtures in tests/fixtures/sysrep.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml

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


class SysRepError(ValueError):
    """A SysRep file is malformed. ``str(err)`` is ``file:line: where: problem``."""

    def __init__(self, path: str | Path, line: int, where: str, problem: str) -> None:
        self.path = str(path)
        self.line = line
        self.where = where
        self.problem = problem
        location = f"{self.path}:{line}" if line else self.path
        super().__init__(f"{location}: {where}: {problem}" if where else f"{location}: {problem}")


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
    """Walks the YAML node tree so every error can name its line."""

    def __init__(self, path: Path) -> None:
        self.path = path

    def fail(self, node: yaml.Node | None, where: str, problem: str) -> SysRepError:
        line = node.start_mark.line + 1 if node is not None else 0
        return SysRepError(self.path, line, where, problem)

    def scalar(self, node: yaml.Node, where: str, what: str) -> str:
        if not isinstance(node, yaml.ScalarNode) or node.tag != "tag:yaml.org,2002:str":
            raise self.fail(node, where, f"{what} must be a string, got {_describe(node)}")
        return str(node.value)

    def identifier(self, node: yaml.Node, where: str, what: str) -> str:
        value = self.scalar(node, where, what)
        if not _IDENTIFIER.match(value):
            raise self.fail(node, where, f"{what} {value!r} is not an identifier (letters, digits, _)")
        return value

    def type_name(self, node: yaml.Node, where: str) -> str:
        value = self.scalar(node, where, "type")
        if value not in TYPES:
            raise self.fail(node, where, f"unknown type {value!r} (expected one of {', '.join(TYPES)})")
        return value

    def extensions(self, node: yaml.Node, where: str, allowed: set[str]) -> dict[str, Any]:
        if not isinstance(node, yaml.MappingNode):
            raise self.fail(node, where, f"extension must be a mapping, got {_describe(node)}")
        data = yaml.safe_load(yaml.serialize(node))
        for key in data:
            if key not in allowed:
                raise self.fail(
                    node, where, f"unknown extension {key!r} (allowed: {', '.join(sorted(allowed))})"
                )
        for key in ("min", "max"):
            if key in data and (isinstance(data[key], bool) or not isinstance(data[key], (int, float))):
                raise self.fail(node, where, f"extension {key!r} must be a number, got {data[key]!r}")
        if "enum" in data and not isinstance(data["enum"], list):
            raise self.fail(node, where, f"extension 'enum' must be a list, got {data['enum']!r}")
        if "hazardous" in data and not isinstance(data["hazardous"], bool):
            raise self.fail(node, where, f"extension 'hazardous' must be true or false, got {data['hazardous']!r}")
        for key in ("units", "description"):
            if key in data and not isinstance(data[key], str):
                raise self.fail(node, where, f"extension {key!r} must be a string, got {data[key]!r}")
        return data

    def value_extensions(self, node: yaml.Node, where: str, type_name: str) -> dict[str, Any]:
        data = self.extensions(node, where, _VALUE_EXTENSIONS)
        if ("min" in data or "max" in data) and type_name not in ("integer", "real"):
            raise self.fail(node, where, f"min/max apply to integer or real, not {type_name}")
        if "enum" in data:
            try:
                data["enum"] = tuple(check_value("enum", type_name, v) for v in data["enum"])
            except ValueError as exc:
                raise self.fail(node, where, f"enum value does not match type {type_name}: {exc}") from None
        return data

    def argument(self, node: yaml.Node, where: str) -> Argument:
        if not isinstance(node, yaml.SequenceNode) or len(node.value) not in (2, 3):
            raise self.fail(node, where, f"argument must be [name, type] or [name, type, {{extensions}}], got {_describe(node)}")
        name = self.identifier(node.value[0], where, "argument name")
        where = f"{where} {name!r}"
        type_name = self.type_name(node.value[1], where)
        ext = self.value_extensions(node.value[2], where, type_name) if len(node.value) == 3 else {}
        return Argument(name=name, type=type_name, **ext)

    def command(self, node: yaml.Node, index: int) -> Command:
        where = f"commands[{index}]"
        if not isinstance(node, yaml.SequenceNode) or len(node.value) not in (3, 4):
            raise self.fail(node, where, f"command must be [id, label, [[arg, type], ...]] (3 or 4 items), got {_describe(node)}")
        command_id = self.identifier(node.value[0], where, "command id")
        where = f"{where} {command_id!r}"
        label = self.scalar(node.value[1], where, "label")
        args_node = node.value[2]
        if not isinstance(args_node, yaml.SequenceNode):
            raise self.fail(args_node, where, f"arguments must be a list of [name, type], got {_describe(args_node)}")
        args: list[Argument] = []
        for i, arg_node in enumerate(args_node.value):
            arg = self.argument(arg_node, f"{where} argument {i + 1}")
            if any(a.name == arg.name for a in args):
                raise self.fail(arg_node, where, f"duplicate argument {arg.name!r}")
            args.append(arg)
        ext = self.extensions(node.value[3], where, _COMMAND_EXTENSIONS) if len(node.value) == 4 else {}
        return Command(command_id, label, tuple(args), line=node.start_mark.line + 1, **ext)

    def telemetry(self, node: yaml.Node, index: int) -> Telemetry:
        where = f"telemetry[{index}]"
        if not isinstance(node, yaml.SequenceNode) or len(node.value) not in (3, 4):
            raise self.fail(node, where, f"telemetry must be [id, label, type] (3 or 4 items), got {_describe(node)}")
        item_id = self.identifier(node.value[0], where, "telemetry id")
        where = f"{where} {item_id!r}"
        label = self.scalar(node.value[1], where, "label")
        type_name = self.type_name(node.value[2], where)
        ext = self.value_extensions(node.value[3], where, type_name) if len(node.value) == 4 else {}
        return Telemetry(item_id, label, type_name, line=node.start_mark.line + 1, **ext)

    def sysrep(self, root: yaml.Node | None) -> SysRep:
        if not isinstance(root, yaml.MappingNode):
            raise self.fail(root, "", f"a SysRep must be a mapping with id, name, commands, telemetry; got {_describe(root)}")
        fields: dict[str, yaml.Node] = {}
        for key_node, value_node in root.value:
            key = self.scalar(key_node, "", "key")
            if key not in _TOP_LEVEL_KEYS:
                raise self.fail(key_node, "", f"unknown key {key!r} (allowed: {', '.join(sorted(_TOP_LEVEL_KEYS))})")
            if key in fields:
                raise self.fail(key_node, "", f"duplicate key {key!r}")
            fields[key] = value_node
        for required in ("id", "name"):
            if required not in fields:
                raise self.fail(root, "", f"missing required key {required!r}")
        sysrep_id = self.identifier(fields["id"], "id", "id")
        name = self.scalar(fields["name"], "name", "name")
        commands = self._entries(fields.get("commands"), "commands", self.command)
        telemetry = self._entries(fields.get("telemetry"), "telemetry", self.telemetry)
        description = self.scalar(fields["description"], "description", "description") if "description" in fields else None
        version = self.scalar(fields["version"], "version", "version") if "version" in fields else None
        return SysRep(sysrep_id, name, tuple(commands), tuple(telemetry), str(self.path), description, version)

    def _entries(self, node: yaml.Node | None, section: str, read: Any) -> list[Any]:
        if node is None or isinstance(node, yaml.ScalarNode) and node.tag == "tag:yaml.org,2002:null":
            return []
        if not isinstance(node, yaml.SequenceNode):
            raise self.fail(node, section, f"{section} must be a list, got {_describe(node)}")
        entries: list[Any] = []
        for index, entry_node in enumerate(node.value):
            entry = read(entry_node, index)
            if any(e.id == entry.id for e in entries):
                raise self.fail(entry_node, f"{section}[{index}] {entry.id!r}", f"duplicate id {entry.id!r}")
            entries.append(entry)
        return entries


def _describe(node: yaml.Node | None) -> str:
    if node is None:
        return "nothing"
    if isinstance(node, yaml.SequenceNode):
        return f"a list of {len(node.value)} items"
    if isinstance(node, yaml.MappingNode):
        return "a mapping"
    if node.tag == "tag:yaml.org,2002:null":
        return "nothing"
    kind = node.tag.rsplit(":", 1)[-1]
    return f"{kind} {node.value!r}"


def load_sysrep(path: str | Path) -> SysRep:
    """Load and validate one SysRep file.

    Raises:
        SysRepError: the file is missing, not YAML, or not a valid SysRep; the message names
            the file, the line, the entry and what is wrong.
    """
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise SysRepError(path, 0, "", f"cannot read: {exc.strerror or exc}") from None
    try:
        root = yaml.compose(text, Loader=yaml.SafeLoader)
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = mark.line + 1 if mark is not None else 0
        problem = getattr(exc, "problem", None) or str(exc)
        raise SysRepError(path, line, "", f"not valid YAML: {problem}") from None
    return _Reader(path).sysrep(root)


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
