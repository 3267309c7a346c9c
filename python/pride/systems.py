"""The systems a procedure commands and reads, seen from PAX: one result type, one telemetry type.

The executive never imports ROS or the JVM. It talks to a :class:`SystemGateway`; the real one
is :class:`pride.pax_host.PaxHost` (the Java PAX plugins in this process), opened by
:func:`pride.gateways.open_gateway`. Every gateway answers with the :class:`CommandResult` and
:class:`TelemetryValue` defined here and calls its listeners with a :class:`TelemetryValue`, so no
caller guesses at a result's shape. This module imports nothing of Caretaker: every gateway,
the executive and the views depend on it, never the other way round.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

__all__ = [
    "CancelResult",
    "CommandResult",
    "LinkListener",
    "LinkState",
    "Outcome",
    "SystemGateway",
    "TelemetryListener",
    "TelemetryValue",
]


class Outcome(str, enum.Enum):
    """What became of a command (the Java plugin API's ``caretaker.pax.Outcome``).

    Only SUCCEEDED is success. UNKNOWN is neither success nor failure: the command may or may not
    have been executed, and an operator decides. The values are the words the audit log records.
    """

    SUCCEEDED = "succeeded"
    """The system carried the command out and said so."""
    FAILED = "failed"
    """The system refused or failed it and said so, or it was certainly never executed."""
    UNKNOWN = "unknown"
    """It may or may not have been executed, and the system could not be asked."""
    HALTED = "halted"
    """It was stopped by a halt (a cancel) before it finished."""


@dataclass(frozen=True)
class CommandResult:
    """What a system answered to a command: it never claims a success the system did not report.

    Every outcome but SUCCEEDED carries a message saying why.
    """

    outcome: Outcome
    message: str = ""
    values: dict[str, Any] = field(default_factory=dict)

    @property
    def success(self) -> bool:
        """Whether the system carried the command out (only :attr:`Outcome.SUCCEEDED`)."""
        return self.outcome is Outcome.SUCCEEDED


@dataclass(frozen=True)
class CancelResult:
    """What a system answered to a cancel of a command in flight.

    ``stopped`` is True when the system confirmed the command stopped (or that nothing was
    running); False when it cannot cancel (a plain ROS service call runs to its end), or the
    cancel did not reach it. ``message`` says which, in the system's words.
    """

    stopped: bool
    message: str


@dataclass(frozen=True)
class LinkState:
    """The link to one robot connection (a rosbridge server), as commands see it.

    ``lost_since`` (epoch seconds) is None while connected; ``in_flight`` counts the commands sent
    or waiting to be sent whose outcome is not known yet. ``quiet_since``: while connected, when
    the server was last heard if nothing has come from it for a few keepalive intervals (a held
    link looks connected until the keepalive gives it up, minutes later).
    """

    link: str
    connected: bool
    lost_since: float | None = None
    in_flight: int = 0
    quiet_since: float | None = None


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
#: ``callback(state)``, called on the gateway's thread when a link goes down or up (and while it is
#: down, when the number of commands in flight changes). Must return quickly.
LinkListener = Callable[[LinkState], None]


@runtime_checkable
class SystemGateway(Protocol):
    """The PAX host shape: commands out (and their cancel), telemetry and link state in."""

    def system_ids(self) -> frozenset[str]:
        """The ids of the SysReps this gateway serves."""

    def robot(self) -> str:
        """The robot the binding names (``robot:``): one run at a time may control it."""

    def execute(
        self, sysrep_id: str, command_id: str, args: Mapping[str, Any], *, key: str | None = None
    ) -> CommandResult:
        """Send a command and block until the system answers.

        The gateway checks every argument against the SysRep and converts it to its type: values
        arrive as the procedure gives them (text written in the procedure, typed values of records,
        inputs and results). It raises an exception, and sends nothing, for a value that does not fit.

        ``key`` (``run/instruction/attempt``) names the command: the habitat executes a key at
        most once, and a re-send of the same key returns its outcome (or joins its execution).
        """

    def cancel(self, key: str) -> CancelResult:
        """Stop the command ``key`` now, if it is still running (a halt): direct, idempotent.

        Returns what the system said; never raises for a command that cannot be cancelled.
        The command's own :meth:`execute` then returns HALTED (or its real outcome, if it
        finished before the cancel reached it).
        """

    def one_way_delay(self) -> float:
        """The binding's expected one-way delay in seconds (0 on one host): telemetry is that old."""

    def telemetry(self, sysrep_id: str, item_id: str) -> TelemetryValue:
        """The current value of an item."""

    def add_listener(self, callback: TelemetryListener) -> None:
        """Call ``callback(sysrep_id, item_id, value)`` whenever a telemetry item changes."""

    def add_link_listener(self, callback: LinkListener) -> None:
        """Call ``callback(state)`` whenever a link goes down or up (see :data:`LinkListener`)."""

    def close(self) -> None:
        """Release the connection to the systems."""
