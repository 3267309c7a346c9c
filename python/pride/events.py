"""What happened during a run: the records the audit log keeps and observers receive.

Every action of a run is one :class:`Event`, numbered per run. The executive creates them; the
audit log (:mod:`records.audit_log`) stores them before anyone else sees them; reports and views
read them. Events are immutable: observing a run never changes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any, Protocol

from pride.event_kinds import EventKind

__all__ = ["PAX", "Availability", "Event", "EventKind", "Journal"]

#: The actor name of everything the automation does by itself.
PAX = "PAX"


@dataclass(frozen=True)
class Event:
    """One recorded action. ``instruction`` is the full number, e.g. ``2.3`` or ``3.1/1.2`` in a sub-procedure."""

    run_id: str
    seq: int
    kind: EventKind
    actor: str
    instruction: str | None = None
    data: dict[str, Any] = field(default_factory=dict)
    time: datetime = field(default_factory=lambda: datetime.now(UTC))

    def to_dict(self) -> dict[str, Any]:
        return {
            "run_id": self.run_id,
            "seq": self.seq,
            "kind": self.kind.value,
            "actor": self.actor,
            "instruction": self.instruction,
            "data": self.data,
            "time": self.time.isoformat(),
        }


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
