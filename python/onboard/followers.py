"""The grounds' requests that follow an onboard run (``/caretaker_onboard/follow``), waiting on the habitat.

A ground learns of an event one light time after it happened only if a request for events is
waiting here when it happens. One request at a time cannot do that: after each answer none waits
for a round trip, and an event then (the run's end among them) waits for the next request to
come. So a following ground keeps sending requests, whatever came back
(:attr:`rosbridge_wire.light_time.LightTime.follow_every`), and several wait here at once. Each
event goes down once: a request is answered only with events no earlier answer on this service
carried (an answer lost with its connection leaves a gap, which the ground closes with a request
to ``/caretaker_onboard/events``: every event above its number). And the newest request waiting
holds what came while it is alone, until the next one arrives behind it or its wait is over (at
most three intervals), so that one is always here for the run's end, which it answers at once.
"""

from __future__ import annotations

import contextlib
import threading
from collections.abc import Callable, Iterator
from dataclasses import dataclass

from records.audit_chain import StoredEvent

__all__ = ["Followers", "Following"]


@dataclass(eq=False)
class Following:
    """One request waiting to follow ``run_id``'s events."""

    run_id: str
    after_seq: int


class Followers:
    """The follow requests waiting on this habitat's runs, and the newest event each run's answers
    carried. ``wake`` wakes every waiting request (a newer one came: the one before it may answer)."""

    def __init__(self, wake: Callable[[], None]) -> None:
        self._wake = wake
        self._lock = threading.Lock()
        self._sent: dict[str, int] = {}  # run -> the newest event an answer carried
        self._waiting: dict[str, list[Following]] = {}  # run -> its requests waiting, oldest first

    @contextlib.contextmanager
    def waiting(self, run_id: str, after_seq: int) -> Iterator[Following]:
        """A request following ``run_id`` while it is answered (the ``with`` block)."""
        following = Following(run_id, max(after_seq, 0))
        with self._lock:
            self._waiting.setdefault(run_id, []).append(following)
        self._wake()
        try:
            yield following
        finally:
            with self._lock:
                waiting = self._waiting[run_id]
                waiting.remove(following)
                if not waiting:
                    del self._waiting[run_id]
            self._wake()  # one behind it may have left to it what was new

    def take(
        self,
        following: Following,
        read: Callable[[int], list[StoredEvent]],
        *,
        ended: bool,
        due: bool,
        limit: int,
    ) -> tuple[list[StoredEvent], int] | None:
        """What to answer ``following`` with now, marked as carried: (events, the habitat's head);
        None while it waits on. ``read(n)`` reads the run's stored events above n; ``ended``: the
        run is over; ``due``: the request's wait is over. What is new goes to the oldest request
        waiting: it was there first, so the run's end goes down in answer to one that was waiting
        when it happened, whichever request's thread the habitat runs first."""
        with self._lock:
            floor = max(following.after_seq, self._sent.get(following.run_id, 0))
            fresh = read(floor)
            waiting = self._waiting[following.run_id]
            if fresh and waiting[0] is not following and not due:
                return None
            alone = waiting[-1] is following
            if not (ended or due or (fresh and (not alone or len(fresh) > limit))):
                return None
            sent = fresh[:limit]
            if sent:
                self._sent[following.run_id] = sent[-1].seq
            return sent, fresh[-1].seq if fresh else floor
