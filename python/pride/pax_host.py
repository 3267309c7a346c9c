"""The Java PAX plugins, hosted in this Python process through JPype: the procedure side's gateway.

The executive talks to systems through :class:`PaxHost`, a :class:`pride.systems.SystemGateway`
(docs/interfaces.md). It runs in the procedure runner on the ground, never on the habitat side::

    host = PaxHost("sysrep/bindings/iva.yaml")
    result = host.execute("cdra", "unlock_filter", {}, key="run-1/2.4/1")  # CommandResult(Outcome, ...)
    host.cancel("run-1/2.7/1")                             # a halt of a command in flight
    locked = host.telemetry("cdra", "filter_locked")     # TelemetryValue(value, timestamp, stale)
    host.add_listener(lambda sysrep, item, value: ...)
    host.add_link_listener(lambda state: ...)  # LinkState(link, connected, lost_since, in_flight, quiet_since)
    host.close()

Everything real happens in Java (``caretaker.binding.PaxHost`` in java/pax-plugins): loading the
binding, connecting to the robot's rosbridge, the plugins. This module converts Python values
to the SysRep's Java types and back, and turns Java exceptions into :class:`PaxError` carrying
the Java message, so a caller never sees a JPype type. Every text from the robot side leaves here
in an operator's words (:func:`pride.at_words.operator_words`): no AT server service name gets past.
"""

from __future__ import annotations

import atexit
import logging
import threading
import uuid
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import jpype

from pride.at_words import operator_words
from pride.jvm import JarNotBuiltError, start_jvm
from pride.systems import (
    CancelResult,
    CommandResult,
    LinkListener,
    LinkState,
    Outcome,
    TelemetryListener,
    TelemetryValue,
)

__all__ = ["JarNotBuiltError", "PaxError", "PaxHost", "to_java", "to_python"]

_LOG = logging.getLogger(__name__)


class PaxError(RuntimeError):
    """The Java side refused or failed: bad binding, unknown command, bad argument, no rosbridge.

    ``str(err)`` is the Java message; ``java_class`` names the Java exception.
    """

    def __init__(self, message: str, java_class: str = "") -> None:
        super().__init__(message)
        self.java_class = java_class


def _java_error(exc: Exception) -> PaxError:
    message = exc.getMessage() if hasattr(exc, "getMessage") else None
    java_class = str(exc.getClass().getName()) if hasattr(exc, "getClass") else type(exc).__name__
    return PaxError(operator_words(str(message)) if message is not None else java_class, java_class)


def to_java(name: str, value: Any) -> Any:
    """A Python argument value as the Java object the SysRep checker expects.

    bool → Boolean, int → Long, float → Double, str → String; anything else is refused here
    rather than handed to Java as an opaque proxy.

    Raises:
        PaxError: the value has no SysRep type.
    """
    if isinstance(value, bool):
        return jpype.JObject(value, jpype.JClass("java.lang.Boolean"))
    if isinstance(value, int):
        return jpype.JObject(value, jpype.JClass("java.lang.Long"))
    if isinstance(value, float):
        return jpype.JObject(value, jpype.JClass("java.lang.Double"))
    if isinstance(value, str):
        return jpype.JString(value)
    raise PaxError(
        f"argument {name!r}: {type(value).__name__} {value!r} is not a SysRep value (string, boolean, integer or real)"
    )


def to_python(value: Any) -> Any:
    """A Java value (String, Boolean, Long/Integer, Double, null, List, Map) as the Python value."""
    if value is None:
        return None
    if not isinstance(value, jpype.JObject):
        return value
    # Java's boxed types subclass Python's int/float in JPype, so test the Java class first:
    # a java.lang.Boolean must become a real bool (``value is False`` must work).
    if isinstance(value, jpype.JClass("java.lang.String")):
        return str(value)
    if isinstance(value, jpype.JClass("java.lang.Boolean")):
        return bool(value.booleanValue())
    if isinstance(value, (jpype.JClass("java.lang.Long"), jpype.JClass("java.lang.Integer"))):
        return int(value.longValue())
    if isinstance(value, jpype.JClass("java.lang.Number")):
        return float(value.doubleValue())
    if isinstance(value, jpype.JClass("java.util.List")):
        return [to_python(item) for item in value]
    if isinstance(value, jpype.JClass("java.util.Map")):
        return {str(key): to_python(item) for key, item in value.items()}
    return str(value.toString())


def _telemetry_value(java_value: Any) -> TelemetryValue:
    stamp = java_value.timestamp()
    timestamp = None if stamp is None else int(stamp.getEpochSecond()) + int(stamp.getNano()) / 1e9
    return TelemetryValue(to_python(java_value.value()), timestamp, bool(java_value.stale()))


class PaxHost:
    """The SysReps of one binding file, served by the Java PAX plugins over rosbridge.

    Args:
        binding_path: a binding file such as ``sysrep/bindings/iva.yaml``.
        rosbridge_url: replaces every rosbridge URL of the binding (e.g. a test server's port).

    Raises:
        JarNotBuiltError: the plugin jar is not built (run ``make setup``).
        PaxError: the binding, a SysRep or a plugin option is wrong, or rosbridge is unreachable.
    """

    def __init__(self, binding_path: str | Path, *, rosbridge_url: str | None = None) -> None:
        start_jvm()
        self._binding_path = Path(binding_path)
        java_host = jpype.JClass("caretaker.binding.PaxHost")
        uri = jpype.JClass("java.net.URI").create(rosbridge_url) if rosbridge_url else None
        path = jpype.JClass("java.nio.file.Path").of(str(self._binding_path), jpype.JArray(jpype.JString)(0))
        try:
            self._host = java_host.open(path, uri)
        except jpype.JException as exc:
            raise _java_error(exc) from None
        # The ids only: the Java host loaded and checks the SysReps; the runner's own copy (the one
        # its lint used) is loaded once by the runner, not again here.
        self._system_ids = frozenset(str(s.id()) for s in self._host.sysReps())
        binding = self._host.binding()
        self._robot = str(binding.robot())
        self._one_way_delay = int(binding.link().oneWayDelay().toMillis()) / 1000.0
        self._listeners: list[Any] = []  # the Java proxies, kept alive while Java holds them
        self._link_listeners: list[Any] = []
        self._closed = False
        self._close_lock = threading.Lock()
        # Java threads must not call Python listeners while the interpreter shuts down (JPype
        # crashes then): a host still open at exit is closed first (atexit runs before that).
        atexit.register(self.close)

    def system_ids(self) -> frozenset[str]:
        """The ids of the bound SysReps."""
        return self._system_ids

    def robot(self) -> str:
        """The binding's ``robot:``."""
        return self._robot

    def one_way_delay(self) -> float:
        """The binding's expected one-way delay (``link: {one_way_delay}``), in seconds."""
        return self._one_way_delay

    def execute(
        self, sysrep_id: str, command_id: str, args: Mapping[str, Any], *, key: str | None = None
    ) -> CommandResult:
        """Execute a SysRep command and wait for the system's real outcome.

        The Java host checks the arguments against its SysRep and converts them; it is the one
        place arguments are checked at run time. It must be: Java integrators call
        ``caretaker.binding.PaxHost.execute`` without Python, so the check cannot move out of it,
        and a second check here would be a second copy of the same rules that could drift from it.
        The procedure side checks what it can know before a run instead (``caretaker lint``).

        Args:
            sysrep_id: a bound SysRep.
            command_id: one of its commands.
            args: every argument of the command; strings are accepted for every type.
            key: the command key ``run/instruction/attempt``: the habitat executes a key at most
                once. Without one, a key of its own is made (the command cannot be re-sent later).

        Returns:
            The system's outcome (:class:`pride.systems.Outcome`); every outcome but SUCCEEDED
            carries its message.

        Raises:
            PaxError: unknown SysRep or command, missing, unknown or ill-typed argument.
        """
        java_args = jpype.JClass("java.util.LinkedHashMap")()
        for name, value in args.items():
            java_args.put(jpype.JString(name), to_java(name, value))
        command_key = key if key is not None else f"unkeyed-{uuid.uuid4().hex}/{command_id}/1"
        try:
            java_key = jpype.JClass("caretaker.pax.CommandKey").parse(jpype.JString(command_key))
            result = self._host.execute(java_key, jpype.JString(sysrep_id), jpype.JString(command_id), java_args)
        except jpype.JException as exc:
            raise _java_error(exc) from None
        values = {str(k): to_python(v) for k, v in result.values().items()}
        outcome = Outcome(str(result.outcome().name()).lower())
        return CommandResult(outcome, operator_words(str(result.message())), values)

    def cancel(self, key: str) -> CancelResult:
        """Stop the command ``key`` if it still runs (``caretaker.binding.PaxHost.cancel``).

        The plugin that sent it cancels it on the system directly; its :meth:`execute` then
        returns HALTED (or its real outcome if it finished first). Never raises for a command that
        cannot be cancelled: the answer says so.

        Raises:
            PaxError: ``key`` is not ``run/instruction/attempt``.
        """
        try:
            answer = self._host.cancel(jpype.JClass("caretaker.pax.CommandKey").parse(jpype.JString(key)))
        except jpype.JException as exc:
            raise _java_error(exc) from None
        return CancelResult(bool(answer.stopped()), operator_words(str(answer.message())))

    def telemetry(self, sysrep_id: str, item_id: str) -> TelemetryValue:
        """The current value, timestamp and staleness of a telemetry item.

        Raises:
            PaxError: unknown SysRep or item.
        """
        try:
            return _telemetry_value(self._host.telemetry(jpype.JString(sysrep_id), jpype.JString(item_id)))
        except jpype.JException as exc:
            raise _java_error(exc) from None

    def add_listener(self, callback: TelemetryListener) -> None:
        """Call ``callback(sysrep_id, item_id, value)`` on every change of value or staleness.

        The callback runs on a Java thread and must return quickly. An exception it raises is
        logged here: Java would otherwise swallow it.
        """

        @jpype.JImplements("caretaker.pax.TelemetryListener")
        class _Listener:
            @jpype.JOverride  # type: ignore[untyped-decorator]  # JPype has no type information
            def telemetryChanged(self, sysrep_id: Any, item_id: Any, value: Any) -> None:  # noqa: N802 (Java name)
                try:
                    callback(str(sysrep_id), str(item_id), _telemetry_value(value))
                except Exception:
                    _LOG.exception("telemetry listener %r failed on %s.%s", callback, sysrep_id, item_id)

        listener = _Listener()
        self._listeners.append(listener)
        self._host.addListener(listener)

    def add_link_listener(self, callback: LinkListener) -> None:
        """Call ``callback(LinkState)`` when a link goes down or up, falls quiet or is heard again
        (and while down or quiet, when the number of commands in flight changes); on a Java
        thread, so it must return quickly."""

        @jpype.JImplements("caretaker.rosbridge.LinkListener")
        class _LinkListener:
            @jpype.JOverride  # type: ignore[untyped-decorator]  # JPype has no type information
            def linkChanged(self, state: Any) -> None:  # noqa: N802 (Java name)
                try:
                    callback(
                        LinkState(
                            str(state.rosbridge().toString()),
                            bool(state.connected()),
                            _epoch(state.lostSince()),
                            int(state.commandsInFlight()),
                            _epoch(state.quietSince()),
                        )
                    )
                except Exception:
                    _LOG.exception("link listener %r failed", callback)

        listener = _LinkListener()
        self._link_listeners.append(listener)
        self._host.addLinkListener(listener)

    def traffic(self) -> dict[str, dict[str, int]]:
        """What each rosbridge connection carried so far: ``{url: {bytes_up, bytes_down,
        messages_up, messages_down}}`` (WebSocket frames; "up" is ground → habitat), for a run's
        summary of what it cost the link."""
        return {
            str(t.rosbridge().toString()): {
                "bytes_up": int(t.bytesUp()),
                "bytes_down": int(t.bytesDown()),
                "messages_up": int(t.messagesUp()),
                "messages_down": int(t.messagesDown()),
            }
            for t in self._host.traffic()
        }

    def close(self) -> None:
        """Stop the plugins and close the rosbridge connections; safe to call twice."""
        with self._close_lock:
            if self._closed:
                return
            self._closed = True
        atexit.unregister(self.close)
        for listener in self._listeners:
            self._host.removeListener(listener)
        for link_listener in self._link_listeners:
            self._host.removeLinkListener(link_listener)
        self._host.close()

    def __enter__(self) -> PaxHost:
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.close()


def _epoch(instant: Any) -> float | None:
    """A java.time.Instant (or null) as epoch seconds."""
    return None if instant is None else int(instant.getEpochSecond()) + int(instant.getNano()) / 1e9
