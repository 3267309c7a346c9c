"""The ground's requests for an onboard run's events, sent so that one is always waiting on the habitat.

One request at a time leaves the habitat without one for a round trip after each answer: an event
then (the run's end among them) waits for the next request to arrive, up to a round trip and a
half after it happened before the ground hears of it. So :class:`FollowRequests` sends a request
to ``/caretaker_onboard/follow`` every :attr:`LightTime.follow_every` (half a round trip),
whatever came back, each waiting on the habitat :attr:`LightTime.follow_wait` (two intervals).
The habitat gives each event to one of them only, and keeps the newest waiting until the next
arrives (:mod:`onboard.followers`): one is always there, so the run's end comes down one light
time after it happened, and any other event within one interval more. No request is sent in
place of one answered: each arrival already lets the one before it answer, and a request per
answer would make answers beget requests. What an answer lost with its connection leaves out,
:meth:`catch_up` asks for: every event above the ground's head, from ``/caretaker_onboard/events``,
at once.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import json
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from rosbridge_wire.client import LinkError, RosbridgeClient
from rosbridge_wire.light_time import LightTime

from .unit import EVENTS_SERVICE, FOLLOW_SERVICE

__all__ = ["FollowAnswer", "FollowRequests"]

#: What the habitat may take to answer a request once its wait is over (a loaded machine).
_ANSWER_WORK_S = 10.0


@dataclass(frozen=True)
class FollowAnswer:
    """The habitat's answer to one request: its values, its events read from ``events_json``, and
    when the request went (the event loop's clock)."""

    values: Mapping[str, Any]
    events: list[Any]
    sent_at: float


class FollowRequests:
    """Requests for ``run_id``'s events above ``head()`` (the ground's newest stored event), kept
    going until :meth:`close`; :meth:`next` gives their answers in the order they came."""

    def __init__(self, client: RosbridgeClient, run_id: str, light_time: LightTime, head: Callable[[], int]) -> None:
        self._client = client
        self._run_id = run_id
        self._every = light_time.follow_every
        self._wait = light_time.follow_wait
        self._head = head
        self._flying: dict[asyncio.Task[Mapping[str, Any]], tuple[float, bool]] = {}  # -> (sent at, follows)
        self._answered: collections.deque[asyncio.Task[Mapping[str, Any]]] = collections.deque()  # as they came
        self._came_back = asyncio.Event()
        self._sent_at = float("-inf")  # the newest follow request's

    def start(self) -> None:
        """Send the first request now unless one is on its way (right behind a unit: the run's
        first events come down as soon as it starts)."""
        if not any(follows for _, follows in self._flying.values()):
            self._send(follows=True)

    def catch_up(self) -> None:
        """Ask at once for every event above the ground's head (a gap, an answer lost), unless that is asked already."""
        if not any(not follows for _, follows in self._flying.values()):
            self._send(follows=False)

    async def next(self) -> FollowAnswer:
        """The next answer to come, sending follow requests meanwhile as the rule says.

        Raises:
            LinkError: a request failed (not connected, lost, unanswered), or its answer is not one.
        """
        loop = asyncio.get_running_loop()
        while not self._answered:
            if loop.time() >= self._sent_at + self._every:
                self._send(follows=True)
            self._came_back.clear()
            with contextlib.suppress(TimeoutError):  # time for the next request
                await asyncio.wait_for(self._came_back.wait(), self._sent_at + self._every - loop.time())
        task = self._answered.popleft()
        sent_at, follows = self._flying.pop(task)
        values = task.result()
        try:
            events = json.loads(str(values.get("events_json", "[]")))
        except ValueError:
            events = None
        if not isinstance(events, list):
            raise LinkError(FOLLOW_SERVICE if follows else EVENTS_SERVICE, "events_json is not a JSON list")
        return FollowAnswer(values, events, sent_at)

    def close(self) -> None:
        """Stop asking (the habitat lets the requests waiting there run out)."""
        for task in self._flying:
            task.cancel()
        self._flying.clear()

    def _send(self, *, follows: bool) -> None:
        loop = asyncio.get_running_loop()
        wait = self._wait if follows else 0.0
        request = {"run_id": self._run_id, "after_seq": self._head(), "wait_s": wait, "max_events": 0}
        service = FOLLOW_SERVICE if follows else EVENTS_SERVICE
        timeout = self._client.call_timeout(wait + _ANSWER_WORK_S)
        task = loop.create_task(self._client.call(service, request, timeout=timeout))
        self._flying[task] = (loop.time(), follows)
        if follows:
            self._sent_at = loop.time()
        task.add_done_callback(self._came)

    def _came(self, task: asyncio.Task[Mapping[str, Any]]) -> None:
        if not task.cancelled():  # cancelled: closed, and forgotten then
            self._answered.append(task)
            self._came_back.set()
