"""Binding files (``sysrep/bindings/*.yaml``) read in Python: the one reader and the one type.

The Java ``caretaker.binding.BindingLoader`` is the reader a run's plugins use; this module
applies its rules (keys, types, plugin names, rosbridge URLs, SysReps loadable and bound once,
the ``link`` and ``security`` sections and the files they name) with the shared :mod:`datafile`
reader, so ``caretaker check`` and ``caretaker up`` name a broken binding by file, line and key
before anything starts, and the console's 3D view finds the robot's bridge with its trust.
Both readers accept and refuse the same fixtures (``tests/fixtures/bindings/``, read by the
Python and the Java tests). Plugin *options* are the plugins' own business and are checked by
the Java loader when a run opens the binding.

A binding that states a ``link:`` is across a real link: its commands go only through the
habitat's command ledger (a habitat without one is refused when the run opens it). Without
``link:`` it is a loopback binding: a habitat without a ledger then gets commands directly.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import urlparse

from datafile import DataFileError, Field, load_file
from procedure_language.sysrep import load_sysrep
from rosbridge_wire.client import Endpoint

__all__ = [
    "BUILT_IN_PLUGINS",
    "BindingError",
    "BindingLink",
    "BindingSecurity",
    "BoundSystem",
    "Binding",
    "read_binding",
]

#: The plugins the Java loader knows by name (caretaker.binding.PluginKind); others are class names.
BUILT_IN_PLUGINS = ("at_commands", "at_telemetry", "ros_convention")
TOP_LEVEL_KEYS = ("robot", "rosbridge", "systems", "description", "link", "security", "ledger_namespace")
LINK_KEYS = ("one_way_delay", "outage_budget")
SECURITY_KEYS = ("ca_file", "secret_file", "token_file")
#: A ROS namespace as the Java loader accepts it for ledger_namespace.
NAMESPACE = re.compile(r"(/[A-Za-z_][A-Za-z0-9_]*)+|/")
#: The Java loader's defaults (caretaker.rosbridge.LinkOptions.loopback()).
LOOPBACK_DELAY_S = 0.0
LOOPBACK_OUTAGE_BUDGET_S = 20.0
ENTRY_KEYS = ("sysrep", "plugins", "namespace", "options", "rosbridge")


class BindingError(DataFileError):
    """A binding file that a run could not open."""


@dataclass(frozen=True)
class BoundSystem:
    """One SysRep the binding serves, and where."""

    sysrep: str  # the SysRep id
    namespace: str
    rosbridge: str


@dataclass(frozen=True)
class BindingLink:
    """The link the binding states (or loopback's defaults): what keepalive and patience follow."""

    one_way_delay: float  # s
    outage_budget: float  # s a command in flight waits for a lost link
    stated: bool  # the file has link: (its commands then need the habitat's command ledger)


@dataclass(frozen=True)
class BindingSecurity:
    """Files the rosbridge connection authenticates and verifies with (absolute paths)."""

    ca_file: Path | None = None
    secret_file: Path | None = None
    token_file: Path | None = None


@dataclass(frozen=True)
class Binding:
    """A binding file as read and checked."""

    path: Path
    robot: str
    systems: tuple[BoundSystem, ...]
    link: BindingLink = BindingLink(LOOPBACK_DELAY_S, LOOPBACK_OUTAGE_BUDGET_S, stated=False)
    security: BindingSecurity = BindingSecurity()
    ledger_namespace: str = ""  # where the habitat's command ledger is ("" = the root namespace)

    def endpoint(self, url: str | None = None) -> Endpoint:
        """The robot's rosbridge as a Python client reaches it: ``url`` (default: the first
        system's), with this binding's trust and link delay. Reads the secret or token file."""

        def read(path: Path | None) -> str | None:
            return path.read_text(encoding="utf-8").strip() if path is not None else None

        return Endpoint(
            url=url or self.systems[0].rosbridge,
            one_way_delay=self.link.one_way_delay,
            ca_file=self.security.ca_file,
            secret=read(self.security.secret_file),
            token=read(self.security.token_file),
        )


def _rosbridge(f: Field) -> str:
    url = f.text()
    try:  # urlparse itself refuses some hosts ("ws://[]:1"), .port a port out of range
        parsed = urlparse(url)
        scheme, host, port = parsed.scheme, parsed.hostname, parsed.port
    except ValueError:
        scheme, host, port = "", None, None
    if scheme not in ("ws", "wss") or not host or port is None:
        raise f.fail(f"{url!r} is not a rosbridge URL like ws://127.0.0.1:9090")
    return url


def _link(f: Field | None) -> BindingLink:
    if f is None:
        return BindingLink(LOOPBACK_DELAY_S, LOOPBACK_OUTAGE_BUDGET_S, stated=False)
    f.mapping(optional=LINK_KEYS)
    delay = f["one_way_delay"].number(min=0.0) if f.has("one_way_delay") else LOOPBACK_DELAY_S
    budget = LOOPBACK_OUTAGE_BUDGET_S
    if f.has("outage_budget"):
        budget = f["outage_budget"].number(min=0.0)
        if budget == 0:
            raise f["outage_budget"].fail("must be a positive number of seconds, got 0")
    return BindingLink(delay, budget, stated=True)


def _secret(f: Field) -> Path:
    path = f.file_path()
    try:
        empty = not path.read_text(encoding="utf-8").strip()
    except (OSError, UnicodeDecodeError) as exc:
        raise f.fail(f"cannot read {path}: {exc}") from None
    if empty:
        raise f.fail(f"{path} is empty; put the bridge's shared secret in it")
    return path


def _security(f: Field | None) -> BindingSecurity:
    if f is None:
        return BindingSecurity()
    f.mapping(optional=SECURITY_KEYS)
    if f.has("secret_file") and f.has("token_file"):
        raise f["token_file"].fail("give secret_file (HMAC) or token_file (bearer token), not both")
    ca_file = f["ca_file"].file_path() if f.has("ca_file") else None
    if ca_file is not None:
        try:
            pem = ca_file.read_text(encoding="utf-8", errors="replace")
        except OSError as exc:
            raise f["ca_file"].fail(f"cannot read {ca_file}: {exc.strerror}") from None
        if "-----BEGIN CERTIFICATE-----" not in pem:
            raise f["ca_file"].fail(f"{ca_file} holds no PEM certificate (-----BEGIN CERTIFICATE-----)")
    return BindingSecurity(
        ca_file=ca_file,
        secret_file=_secret(f["secret_file"]) if f.has("secret_file") else None,
        token_file=_secret(f["token_file"]) if f.has("token_file") else None,
    )


def read_binding(path: str | Path) -> Binding:
    """Read and check a binding file and every SysRep it names.

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
            raise entry["sysrep"].fail(
                f"SysRep {sysrep.id!r} is bound twice; bind each SysRep once (list several plugins instead)"
            )
        systems.append(BoundSystem(sysrep.id, namespace, bridge))
    link = _link(root.get("link"))
    ledger_namespace = ""
    if root.has("ledger_namespace"):
        ledger_namespace = root["ledger_namespace"].text()
        if not NAMESPACE.fullmatch(ledger_namespace):
            raise root["ledger_namespace"].fail(f"must be a ROS namespace like /iva, got {ledger_namespace!r}")
    return Binding(
        path,
        robot,
        tuple(systems),
        link,
        _security(root.get("security")),
        "" if ledger_namespace == "/" else ledger_namespace,
    )
