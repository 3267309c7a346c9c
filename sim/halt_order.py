"""The robot's order of halts and motion requests: nothing issued before a halt starts after it.

A trajectory goal or a gripper request can cross a halt on its way: sent before the halt, it
reaches the controller after it, or waits for a thread while the halt is served. Two things keep
it from moving the robot then. The halts are counted, and a request notes the count when it
arrives, so one that arrived before a halt never starts after it. And a request says when its
command reached the robot side (``issued``, :mod:`ros_process.command_order`), and a halt when it
did (``arrived``: the AT server's halt says when it reached the server), so one whose command was
issued before a halt never starts, however late it arrives here. A request without a stamp was
issued when it arrived.

All calls under the simulation's world lock, with the halt itself, so a request is either refused
or started before the halt stops it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ros_process.command_order import arrived_now, issued_at

__all__ = ["HaltOrder", "Ticket"]


@dataclass(frozen=True)
class Ticket:
    """A motion request as it arrived: the halts so far, and when its command was issued."""

    halts: int
    issued: float


class HaltOrder:
    """The halts the robot has seen, and the motion requests that arrived and have not started."""

    def __init__(self) -> None:
        self.halts = 0
        self._latest = -math.inf  # when the latest halt reached the robot side (s, its clock)
        self._reason = ""
        self._waiting: dict[int, Ticket] = {}  # goals accepted and not yet begun, by request key

    def halted(self, reason: str, arrived: Any) -> None:
        """A halt for ``reason``; ``arrived`` its stamp (builtin_interfaces/Time, zero: now)."""
        self.halts += 1
        self._latest = max(self._latest, issued_at(arrived, arrived_now()))
        self._reason = reason

    def ticket(self, issued: Any) -> Ticket:
        """A motion request arrives now; ``issued`` its command's stamp (None or zero: now)."""
        now = arrived_now()
        return Ticket(self.halts, now if issued is None else issued_at(issued, now))

    def arrived(self, key: int, issued: Any) -> None:
        """Goal ``key`` arrived; it begins in another callback, which :meth:`take` s its ticket."""
        self._waiting[key] = self.ticket(issued)

    def take(self, key: int) -> Ticket:
        """The ticket of goal ``key``, no longer waiting (one not noted on arrival arrives now)."""
        return self._waiting.pop(key, None) or self.ticket(None)

    def refusal(self, ticket: Ticket) -> str | None:
        """Why the request of ``ticket`` must not start now, or None."""
        if ticket.halts != self.halts:
            return f"halted ({self._reason}) before it started: nothing moved"
        if ticket.issued <= self._latest:
            return f"halted ({self._reason}) before it started (its command was issued before the halt): nothing moved"
        return None
