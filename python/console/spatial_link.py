"""Which robot the ground's 3D view reads, and over which rosbridge link (from the run's binding).

Why a Python client here and not the Java connection of the run's PAX host: the web server is
asyncio and only reads (latched topics, throttled topics, read-only services); the PAX host's
connection lives in a JVM behind JPype, whose threads would have to call back into the event
loop for every frame, and its API is shaped for commands and typed telemetry. Commands still go
only through PAX (``Executive.operator_command``); the view's :class:`RosbridgeClient` never
sends one. It uses the binding's own rosbridge address and ``security`` (CA file, HMAC secret
or token, as the Java client does) and its ``link`` delay for timeouts, so it crosses the same
link with the same trust; every subscription asks for a bounded rate (``throttle_rate``,
``queue_length: 1``).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from procedure_language.binding import read_binding
from rosbridge_wire.client import Endpoint

__all__ = ["ViewLink", "read_view_link"]

AT_NAMESPACE_SUFFIX = "/affordance_template_server"


@dataclass(frozen=True)
class ViewLink:
    """What the view needs of a binding: where its robot's rosbridge is, with what trust, and
    the robot's namespace (the AT server's namespace less ``/affordance_template_server``)."""

    endpoint: Endpoint
    namespace: str

    def name(self, relative: str) -> str:
        """A robot-relative ROS name (``joint_states``) under the robot's namespace."""
        return f"{self.namespace.rstrip('/')}/{relative}"


def read_view_link(path: str | Path, *, rosbridge_url: str | None = None) -> ViewLink | None:
    """The binding's link for the view (read by :func:`procedure_language.binding.read_binding`), or None when
    it serves no Affordance Template system (nothing to show in 3D). ``rosbridge_url`` replaces
    the binding's address, as for PAX."""
    binding = read_binding(path)
    at_system = next((s for s in binding.systems if s.namespace.endswith(AT_NAMESPACE_SUFFIX)), None)
    if at_system is None:
        return None
    return ViewLink(
        endpoint=binding.endpoint(rosbridge_url or at_system.rosbridge),
        namespace=at_system.namespace[: -len(AT_NAMESPACE_SUFFIX)] or "/",
    )
