"""The ground's requests for an onboard run's events, sent so that one is always waiting on the habitat.

One request at a time leaves the habitat without one for a round trip after each answer: an event
then (the run's end among them) waits for the next request to arrive, up to a round trip and a
half after it happened before the ground hears of it. So :class:`FollowRequests` sends a request
to ``/caretaker_onboard/follow`` every :attr:`LightTime.follow_every` (half a round trip) from
the unit on, whatever came back and whether or not anyone reads the answers yet (the unit's own
answer takes a round trip, and a short run ends before it), each waiting on the habitat
:attr:`LightTime.follow_wait` (three intervals). The habitat gives each event to one of them
only, and keeps the newest waiting until the next arrives (:mod:`onboard.followers`): one is
always there, so the run's end comes down one light time after it happened, and any other event
within one interval more. No request is sent in
place of one answered: each arrival already lets the one before it answer, and a request per
answer would make answers beget requests. What an answer lost with its connection leaves out,
:meth:`catch_up` asks for: every event above the ground's head, from ``/caretaker_onboard/events``,
at once.
"""

from __future__ import annotations

import asyncio
import collections
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
        self._sender: asyncio.Task[None] | None = None

    def start(self) -> None:
        """Start sending: the first request now (right behind a unit: the run's first events come
        down as soon as it starts), then one every interval until :meth:`close`, whether or not
        anyone is reading the answers yet (the unit's own answer takes a round trip)."""
        if self._sender is None:
            self._sender = asyncio.get_running_loop().create_task(self._sending())

    def catch_up(self) -> None:
        """Ask at once for every event above the ground's head (a gap, an answer lost), unless that is asked already."""
        if not any(not follows for _, follows in self._flying.values()):
            self._send(follows=False)

    async def next(self) -> FollowAnswer:
        """The next answer to come, in the order they came.

        Raises:
            LinkError: a request failed (not connected, lost, unanswered), or its answer is not one.
        """
        while not self._answered:
            self._came_back.clear()
            await self._came_back.wait()
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
        if self._sender is not None:
            self._sender.cancel()
        for task in self._flying:
            task.cancel()
        self._flying.clear()

    async def _sending(self) -> None:
        """A follow request every interval while the session is open (none while it is down:
        the catch-up after it asks for what was missed)."""
        while True:
            await self._client.opened.wait()
            self._send(follows=True)
            await asyncio.sleep(self._every)

    def _send(self, *, follows: bool) -> None:
        loop = asyncio.get_running_loop()
        wait = self._wait if follows else 0.0
        request = {"run_id": self._run_id, "after_seq": self._head(), "wait_s": wait, "max_events": 0}
        service = FOLLOW_SERVICE if follows else EVENTS_SERVICE
        timeout = self._client.call_timeout(wait + _ANSWER_WORK_S)
        task = loop.create_task(self._client.call(service, request, timeout=timeout))
        self._flying[task] = (loop.time(), follows)
        task.add_done_callback(self._came)

    def _came(self, task: asyncio.Task[Mapping[str, Any]]) -> None:
        if not task.cancelled():  # cancelled: closed, and forgotten then
            self._answered.append(task)
            self._came_back.set()
