"""What the record holds of monitors (:mod:`pride.monitoring`): a violation, a value's return, and
the go-to a violation made. Part of :data:`pride.event_payloads.Payload`, which every fold matches."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from pride.event_json import JSON_NAME, Recorded
from pride.event_kinds import EventKind

__all__ = ["MonitorCleared", "MonitorViolated", "WentTo"]


@dataclass(frozen=True, kw_only=True)
class MonitorViolated(Recorded):
    """A monitor (:mod:`pride.monitoring`) saw its item out for its persistence: ``monitor`` (its
    name: item and step), ``system``, ``telemetry``, ``value``, ``limit`` (what the value is out
    of, in words), ``action`` (``hold``, ``halt`` or ``goto:STEP``), ``text`` (the monitor's own
    words). The event's instruction is the one in progress."""

    KIND = EventKind.MONITOR_VIOLATED
    monitor: str
    system: str
    telemetry: str
    value: Any
    limit: str
    action: str
    text: str


@dataclass(frozen=True, kw_only=True)
class MonitorCleared(Recorded):
    """A violated monitor's item came back within it: ``monitor``, ``system``, ``telemetry``, ``value``."""

    KIND = EventKind.MONITOR_CLEARED
    monitor: str
    system: str
    telemetry: str
    value: Any


@dataclass(frozen=True, kw_only=True)
class WentTo(Recorded):
    """The run went to a step by no instruction of its own (a monitor's go-to, once what was in
    progress ended): ``from_`` (stored as ``from``) where it was, ``next`` where it continues,
    ``reason``."""

    KIND = EventKind.WENT_TO
    from_: str = field(metadata={JSON_NAME: "from"})
    next: str
    reason: str
