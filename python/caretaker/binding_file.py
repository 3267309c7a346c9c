"""Checking binding files (``sysrep/bindings/*.yaml``) without a JVM.

The Java ``caretaker.binding.BindingLoader`` is the reader a run uses; this check applies its
rules (keys, types, plugin names, rosbridge URLs, SysReps loadable and bound once) with the
shared :mod:`datafile` reader, so ``caretaker check`` and ``caretaker up`` can name a broken
binding by file, line and key before anything starts. Plugin *options* are the plugins' own
business and are checked by the Java loader when a run opens the binding.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlparse

from datafile import DataFileError, Field, load_file
from pride.sysrep import load_sysrep

__all__ = ["BUILT_IN_PLUGINS", "BindingError", "BoundSystem", "BindingSummary", "check_binding"]

#: The plugins the Java loader knows by name (caretaker.binding.PluginKind); others are class names.
BUILT_IN_PLUGINS = ("at_commands", "at_telemetry", "ros_convention")
TOP_LEVEL_KEYS = ("robot", "rosbridge", "systems", "description")
ENTRY_KEYS = ("sysrep", "plugins", "namespace", "options", "rosbridge")


class BindingError(DataFileError):
    """A binding file that a run could not open."""


@dataclass(frozen=True)
class BoundSystem:
    sysrep: str  # the SysRep id
    namespace: str
    rosbridge: str


@dataclass(frozen=True)
class BindingSummary:
    path: Path
    robot: str
    systems: tuple[BoundSystem, ...]


def _rosbridge(f: Field) -> str:
    url = f.text()
    parsed = urlparse(url)
    try:
        port = parsed.port
    except ValueError:
        port = None
    if parsed.scheme not in ("ws", "wss") or not parsed.hostname or port is None:
        raise f.fail(f"{url!r} is not a rosbridge URL like ws://127.0.0.1:9090")
    return url


def check_binding(path: str | Path) -> BindingSummary:
    """Check a binding file and every SysRep it names.

    Raises:
        BindingError: ``file:line: key: problem`` for the binding itself.
        SysRepError: for a SysRep it names.
    """
    path = Path(path)
    root = load_file(path, error=BindingError).mapping(required=("robot", "systems"), optional=TOP_LEVEL_KEYS)
    robot = root["robot"].text()
    default_bridge = _rosbridge(root["rosbridge"]) if root.has("rosbridge") else ""
    systems: list[BoundSystem] = []
    for entry in root["systems"].sequence(min_items=1):
        entry.mapping(required=("sysrep", "plugins"), optional=ENTRY_KEYS)
        sysrep_file = entry["sysrep"].file_path()
        sysrep = load_sysrep(sysrep_file)
        for plugin in entry["plugins"].sequence(min_items=1):
            name = plugin.text()
            if name not in BUILT_IN_PLUGINS and "." not in name:
                raise plugin.fail(f"unknown plugin {name!r} (built in: {', '.join(BUILT_IN_PLUGINS)}; or a class name)")
        if entry.has("options"):
            for key, value in entry["options"].entries():
                if value.node.kind != "scalar":
                    raise value.fail(f"option {key!r} must be a single value, got {value.describe()}")
        namespace = entry["namespace"].text() if entry.has("namespace") else ""
        bridge = _rosbridge(entry["rosbridge"]) if entry.has("rosbridge") else default_bridge
        if not bridge:
            raise entry.fail("no rosbridge URL (set rosbridge at the top or here)")
        if any(s.sysrep == sysrep.id for s in systems):
            raise entry["sysrep"].fail(f"SysRep {sysrep.id!r} is bound twice; bind each SysRep once (list several plugins instead)")
        systems.append(BoundSystem(sysrep.id, namespace, bridge))
    return BindingSummary(path, robot, tuple(systems))
