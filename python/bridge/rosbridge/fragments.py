"""Reassembly of incoming rosbridge ``fragment`` messages, within the bridge's limits.

A client may split one message into ``fragment`` ops (``id``, ``data``, ``num``, ``total``).
The reassembled message obeys the same size limit as a single frame, counted as the parts
arrive (a part sent twice replaces the first, and is counted so), and a connection may have
at most ``max_pending_fragments`` messages in reassembly, whose parts count together against
``max_message_size``; all connections together hold at most ``max_total_fragment_bytes``.
Incomplete messages are dropped after ``fragment_timeout``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

from .limits import Limits, option
from .protocol import InvalidField, OverQuota, describe


@dataclass
class PendingMessage:
    """The parts of one fragmented message received so far."""

    total: int
    started: float
    parts: dict[int, str] = field(default_factory=dict)
    size: int = 0


class Reassembly:
    """Pending fragmented messages of every connection."""

    def __init__(self, limits: Limits) -> None:
        self.limits = limits
        self._pending: dict[int, dict[Any, PendingMessage]] = {}
        self.total_bytes = 0

    def add(self, session: int, fragment_id: Any, data: str, num: int, total: int) -> str | None:
        """Take one part; the whole message text once its last part arrived, else None.

        Raises:
            InvalidField: the part contradicts the earlier ones or the message is too big.
            OverQuota: too many messages in reassembly here or too many bytes on the bridge.
        """
        if not 0 <= num < total:
            raise InvalidField(f"fragment num {num} of total {total} is out of range")
        if total > self.limits.max_message_size:
            raise InvalidField(
                f"a message of {total} fragments exceeds {self.limits.max_message_size} bytes "
                f"({option('max_message_size')})"
            )
        mine = self._pending.setdefault(session, {})
        self._expire(session, mine)
        pending = mine.get(fragment_id)
        if pending is None:
            if len(mine) >= self.limits.max_pending_fragments:
                raise OverQuota(
                    f"too many fragmented messages in reassembly on this connection (limit "
                    f"{self.limits.max_pending_fragments}, {option('max_pending_fragments')})"
                )
            pending = mine[fragment_id] = PendingMessage(total, time.monotonic())
        if pending.total != total:
            self._drop(session, fragment_id)
            raise InvalidField(f"fragment {describe(fragment_id)}: total changed from {pending.total} to {total}")
        growth = len(data) - len(pending.parts.get(num, ""))
        connection_bytes = sum(p.size for p in mine.values())
        if connection_bytes + growth > self.limits.max_message_size:
            self._drop(session, fragment_id)
            raise InvalidField(
                f"fragmented message {describe(fragment_id)} exceeds {self.limits.max_message_size} "
                f"bytes with the others in reassembly ({option('max_message_size')})"
            )
        if self.total_bytes + growth > self.limits.max_total_fragment_bytes:
            self._drop(session, fragment_id)
            raise OverQuota(
                f"too many bytes of fragments in reassembly on this bridge ({option('max_total_fragment_bytes')})"
            )
        pending.parts[num] = data
        pending.size += growth
        self.total_bytes += growth
        if len(pending.parts) < total:
            return None
        self._drop(session, fragment_id)
        return "".join(pending.parts[i] for i in range(total))

    def _expire(self, session: int, mine: dict[Any, PendingMessage]) -> None:
        now = time.monotonic()
        for stale in [k for k, v in mine.items() if now - v.started > self.limits.fragment_timeout]:
            self._drop(session, stale)

    def _drop(self, session: int, fragment_id: Any) -> None:
        pending = self._pending.get(session, {}).pop(fragment_id, None)
        if pending is not None:
            self.total_bytes -= pending.size

    def forget(self, session: int) -> None:
        """Drop every pending message of a closed connection."""
        for pending in self._pending.pop(session, {}).values():
            self.total_bytes -= pending.size
