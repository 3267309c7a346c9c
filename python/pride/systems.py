"""The shape of the systems a procedure commands and reads: the PAX host, seen from PAX.

The executive never imports ROS or the JVM. It talks to a :class:`SystemGateway`: anything with
the methods of ``bridge.pax_host.PaxHost`` (docs/interfaces.md). ``caretaker run --binding FILE``
opens the real host with :func:`open_gateway`.

The environment variable ``PRIDE_GATEWAY=module:factory`` replaces the host with another
gateway factory called with the binding path; it exists so a runner can be driven against a
gateway a test controls in a separate, killable process (tests/pride/test_resume.py).
"""

from __future__ import annotations

import importlib
import os
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

__all__ = ["CommandResult", "SystemGateway", "TelemetryListener", "TelemetryValue", "gateway_system_ids", "open_gateway"]

GATEWAY_ENV = "PRIDE_GATEWAY"


@dataclass(frozen=True)
class CommandResult:
    """What a system answered to a command: success, a message, and named values."""

    success: bool
    message: str = ""
    values: dict[str, Any] = field(default_factory=dict)


@dataclass(frozen=True)
class TelemetryValue:
    """The current value of a telemetry item; ``stale`` when it stopped updating."""

    value: Any
    timestamp: float
    stale: bool = False


TelemetryListener = Callable[[str, str, Any], None]


@runtime_checkable
class SystemGateway(Protocol):
    """The PAX host shape: commands out, telemetry in. Results may be any object with the same fields."""

    def sysreps(self) -> Any:
        """The SysReps this gateway serves (ids, SysRep objects, or a mapping keyed by id)."""

    def execute(self, sysrep_id: str, command_id: str, args: dict[str, Any]) -> Any:
        """Send a command and block until the system answers with a CommandResult."""

    def telemetry(self, sysrep_id: str, item_id: str) -> Any:
        """The current TelemetryValue of an item."""

    def add_listener(self, callback: TelemetryListener) -> None:
        """Call ``callback(sysrep_id, item_id, value)`` whenever a telemetry item changes."""

    def close(self) -> None:
        """Release the connection to the systems."""


def gateway_system_ids(gateway: SystemGateway) -> set[str]:
    """The SysRep ids a gateway serves, whatever collection form its ``sysreps()`` returns."""
    served = gateway.sysreps()
    items: Iterable[Any] = served.keys() if isinstance(served, dict) else served
    return {item if isinstance(item, str) else str(getattr(item, "id")) for item in items}


def open_gateway(binding_path: str, *, rosbridge_url: str | None = None) -> SystemGateway:
    """Open the gateway for a binding file: the PAX host, or the factory named by ``PRIDE_GATEWAY``.

    ``rosbridge_url`` replaces the binding's rosbridge address (a robot served on another port).
    """
    spec = os.environ.get(GATEWAY_ENV)
    if spec:
        module_name, _, factory_name = spec.partition(":")
        if not factory_name:
            raise ValueError(f"{GATEWAY_ENV}={spec!r}: expected module:factory")
        factory = getattr(importlib.import_module(module_name), factory_name)
        return factory(binding_path)
    from bridge.pax_host import PaxHost  # the JVM loads only when a real run needs it

    return PaxHost(binding_path, rosbridge_url=rosbridge_url) if rosbridge_url else PaxHost(binding_path)
