"""The systems a procedure commands and reads, seen from PAX: one result type, one telemetry type.

The executive never imports ROS or the JVM. It talks to a :class:`SystemGateway`; the real one
is :class:`pride.pax_host.PaxHost` (the Java PAX plugins in this process), opened by
:func:`pride.gateways.open_gateway`. Every gateway answers with the :class:`CommandResult` and
:class:`TelemetryValue` defined here and calls its listeners with a :class:`TelemetryValue`, so no
caller guesses at a result's shape. This module imports nothing of Caretaker: every gateway,
the executive and the views depend on it, never the other way round.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

__all__ = ["CommandResult", "SystemGateway", "TelemetryListener", "TelemetryValue"]


@dataclass(frozen=True)
class CommandResult:
    """What a system answered to a command: it never claims a success the system did not report."""

    success: bool
    message: str = ""
    values: dict[str, Any] = field(default_factory=dict)
    outcome: str = ""  # succeeded, failed, unknown or halted (unknown is never success nor failure)


@dataclass(frozen=True)
class TelemetryValue:
    """A telemetry item's value, when it was valid (epoch seconds), and whether it is stale.

    ``value`` and ``timestamp`` are None until the item is first received (then ``stale`` is True).
    """

    value: Any
    timestamp: float | None
    stale: bool = False


#: ``callback(sysrep_id, item_id, value)``, called on the gateway's thread on every change.
TelemetryListener = Callable[[str, str, TelemetryValue], None]


@runtime_checkable
class SystemGateway(Protocol):
    """The PAX host shape: commands out, telemetry in."""

    def system_ids(self) -> frozenset[str]:
        """The ids of the SysReps this gateway serves."""

    def execute(self, sysrep_id: str, command_id: str, args: Mapping[str, Any]) -> CommandResult:
        """Send a command and block until the system answers.

        The gateway checks every argument against the SysRep and converts it to its type: values
        arrive as the procedure gives them (text written in the procedure, typed values of records,
        inputs and results). It raises an exception, and sends nothing, for a value that does not fit.
        """

    def telemetry(self, sysrep_id: str, item_id: str) -> TelemetryValue:
        """The current value of an item."""

    def add_listener(self, callback: TelemetryListener) -> None:
        """Call ``callback(sysrep_id, item_id, value)`` whenever a telemetry item changes."""

    def close(self) -> None:
        """Release the connection to the systems."""
