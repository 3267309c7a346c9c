"""What happened during a run: the records the audit log keeps and observers receive.

Every action of a run is one :class:`Event`, numbered per run. The executive creates them; the
audit log (:mod:`records.audit_log`) stores them before anyone else sees them; reports and views
read them. Events are immutable: observing a run never changes it.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Protocol

from pride.event_kinds import EventKind
from pride.event_payloads import Payload, RunStarted, payload_from_json

__all__ = ["PAX", "Availability", "Event", "EventKind", "Journal", "Payload", "run_start"]

#: The actor name of everything the automation does by itself.
PAX = "PAX"


@dataclass(frozen=True)
class Event:
    """One recorded action. ``instruction`` is the full number, e.g. ``2.3`` or ``3.1/1.2`` in a sub-procedure.

    ``data`` is the kind's payload; given as its stored JSON object (or left out: nothing
    recorded), it is read into that payload (:func:`pride.event_payloads.payload_from_json`,
    which raises :class:`~pride.event_payloads.EventDataError` on a value of the wrong type).
    """

    run_id: str
    seq: int
    kind: EventKind
    actor: str
    instruction: str | None = None
    data: Payload = None  # type: ignore[assignment]  # read from {} in __post_init__
    time: datetime = field(default_factory=lambda: datetime.now(UTC))

    def __post_init__(self) -> None:
        data: object = self.data
        if data is None or isinstance(data, Mapping):
            object.__setattr__(self, "data", payload_from_json(self.kind, data or {}))
        elif self.data.KIND is not self.kind:
            raise ValueError(f"a {self.kind.value} event cannot carry {type(self.data).__name__}")

    @classmethod
    def of(cls, run_id: str, seq: int, actor: str, instruction: str | None, data: Payload) -> Event:
        """The event that records ``data`` (its kind is the payload's)."""
        return cls(run_id, seq, data.KIND, actor, instruction, data)

    def to_dict(self) -> dict[str, Any]:
        return {
            "run_id": self.run_id,
            "seq": self.seq,
            "kind": self.kind.value,
            "actor": self.actor,
            "instruction": self.instruction,
            "data": self.data.to_json(),
            "time": self.time.isoformat(),
        }


def run_start(events: Sequence[Event]) -> RunStarted | None:
    """What a run's log says it started with (its first event), or None when it holds no start."""
    first = events[0].data if events else None
    return first if isinstance(first, RunStarted) else None


@dataclass(frozen=True)
class Availability:
    """Whether appends reach the journal's store; ``since`` is when the current outage began (UTC)."""

    available: bool
    since: datetime | None = None
    error: str = ""


class Journal(Protocol):
    """Where a run's events go first, durably, before the run proceeds."""

    def append(self, event: Event) -> None:
        """Store the event durably; raise if it could not be stored (the run must not go on unrecorded).

        May block while the store is unreachable (the audit log waits out an outage, up to its
        budget), so the caller's next action waits for the record, as it must.
        """

    @property
    def availability(self) -> Availability:
        """Whether appends reach the store now (read without waiting, during an outage too)."""
