"""The audit log's hash chain: each stored event carries a hash of its run's previous event.

An event's hash is SHA-256 over the canonical JSON (sorted keys, no spaces, UTF-8) of exactly
what is stored for it, including the previous event's hash::

    {"actor": .., "data": <the stored JSON text>, "instruction": .., "kind": .., "prev": <64 hex>,
     "run_id": .., "seq": n, "time": "2026-11-23T19:52:00.123456+00:00"}

The first event of a run links to :data:`GENESIS`. Editing a stored event changes its hash;
rewriting its hash too breaks the next event's link; removing an event leaves a gap in the
sequence numbers. :func:`verify_chain` finds the first such event. What a chain alone cannot
show is a removed *tail* (the last events of a run) or a whole chain recomputed by someone
who can write the table: the grants keep runners from both, and the head hash
:func:`verify_chain` reports can be kept elsewhere to compare later (docs/ground-segment.md).
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import UTC, datetime

__all__ = ["GENESIS", "ChainCheck", "StoredEvent", "link_hash", "utc", "verify_chain"]

#: What the first event of every run links to.
GENESIS = "0" * 64


def utc(moment: datetime) -> datetime:
    """The same instant in UTC; a naive time is UTC already (SQLite drops the zone)."""
    return moment.replace(tzinfo=UTC) if moment.tzinfo is None else moment.astimezone(UTC)


@dataclass(frozen=True)
class StoredEvent:
    """One audit record as the database holds it (``data`` is the stored JSON text)."""

    run_id: str
    seq: int
    time: datetime
    actor: str
    kind: str
    instruction: str | None
    data: str
    prev_hash: str
    hash: str = ""

    def expected_hash(self) -> str:
        return link_hash(
            self.prev_hash,
            run_id=self.run_id,
            seq=self.seq,
            time=self.time,
            actor=self.actor,
            kind=self.kind,
            instruction=self.instruction,
            data=self.data,
        )


def link_hash(
    prev_hash: str, *, run_id: str, seq: int, time: datetime, actor: str, kind: str, instruction: str | None, data: str
) -> str:
    """The hash an event with these stored fields carries after ``prev_hash``."""
    canonical = json.dumps(
        {
            "actor": actor,
            "data": data,
            "instruction": instruction,
            "kind": kind,
            "prev": prev_hash,
            "run_id": run_id,
            "seq": seq,
            "time": utc(time).isoformat(timespec="microseconds"),
        },
        sort_keys=True,
        separators=(",", ":"),
        ensure_ascii=False,
    )
    return hashlib.sha256(canonical.encode("utf-8")).hexdigest()


@dataclass(frozen=True)
class ChainCheck:
    """Outcome of checking one run's chain: ``bad_seq`` is the first event that fails, if any."""

    run_id: str
    events: int
    head: str
    bad_seq: int | None = None
    problem: str = ""

    @property
    def ok(self) -> bool:
        return self.bad_seq is None and self.events > 0

    def describe(self) -> str:
        if self.ok:
            return f"run {self.run_id}: chain of {self.events} events intact; head {self.head}"
        if self.events == 0 and self.bad_seq is None:
            return f"run {self.run_id}: no events"
        return f"run {self.run_id}: {self.problem} ({self.events} events before it verified)"


def verify_chain(run_id: str, events: Iterable[StoredEvent]) -> ChainCheck:
    """Check a run's stored events, in sequence order, and name the first one that breaks the chain."""
    prev, expected, checked = GENESIS, 1, 0
    for event in events:
        label = f"event {event.seq} ({event.kind}{' at ' + event.instruction if event.instruction else ''})"
        if event.seq != expected:
            missing = f"event {expected}" if event.seq == expected + 1 else f"events {expected} to {event.seq - 1}"
            return ChainCheck(run_id, checked, prev, event.seq, f"{label} follows a gap: {missing} removed")
        if event.prev_hash != prev:
            return ChainCheck(
                run_id,
                checked,
                prev,
                event.seq,
                f"{label} does not link to event {event.seq - 1}: that event was replaced or its hash rewritten"
                if event.seq > 1
                else f"{label} does not start the chain (its link is not the genesis)",
            )
        if event.expected_hash() != event.hash:
            return ChainCheck(
                run_id,
                checked,
                prev,
                event.seq,
                f"{label} was changed after it was written: its contents do not match its hash",
            )
        prev, expected, checked = event.hash, expected + 1, checked + 1
    return ChainCheck(run_id, checked, prev)
