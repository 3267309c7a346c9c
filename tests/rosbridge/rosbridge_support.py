"""Helpers of the rosbridge tests: awaitable inboxes and graph-matching publish."""

from __future__ import annotations

import contextlib
import json
import re
import threading
import time
from collections.abc import Callable
from typing import Any

import roslibpy


class Inbox:
    """Messages received by callbacks, awaitable by count (no sleeps)."""

    def __init__(self) -> None:
        self.items: list[Any] = []
        self._condition = threading.Condition()

    def __call__(self, item: Any) -> None:
        with self._condition:
            self.items.append(item)
            self._condition.notify_all()

    def reached(self, count: int, timeout: float) -> bool:
        """Whether ``count`` items arrived within ``timeout`` (waits on the condition)."""
        with self._condition:
            return self._condition.wait_for(lambda: len(self.items) >= count, timeout)

    def wait_for(self, count: int, timeout: float = 20.0, *, counted: Callable[[Any], bool] = lambda _: True) -> list[Any]:
        """All items, once ``count`` of them satisfy ``counted`` (by default: any item)."""
        def enough() -> bool:
            return sum(1 for item in self.items if counted(item)) >= count

        with self._condition:
            self._condition.wait_for(enough, timeout)
            assert enough(), f"got {sum(1 for i in self.items if counted(i))} of {count} messages: {self.items[:5]}"
            return list(self.items)


def publish_until_received(topic: roslibpy.Topic, message: dict[str, Any], inbox: Inbox, timeout: float = 20.0) -> int:
    """Publish ``message`` until ``inbox`` gets something: ROS matches publishers to
    subscribers asynchronously, so the first messages of a new publisher may go nowhere.
    Returns the number of items in the inbox afterwards."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        topic.publish(roslibpy.Message(message))
        if inbox.reached(1, 0.1):
            return len(inbox.items)
    raise AssertionError(f"nothing received on {topic.name} within {timeout} s")


class RawClient:
    """A bare WebSocket client speaking JSON frames (no client library in the way)."""

    def __init__(self, host: str, port: int, **options: Any) -> None:
        from websockets.sync.client import connect

        self._stack = contextlib.ExitStack()
        # An unbounded receive queue: frames the test never reads must not stall the closing handshake.
        options.setdefault("max_queue", None)
        self.connection = self._stack.enter_context(connect(f"ws://{host}:{port}", open_timeout=20, **options))

    def send(self, message: dict[str, Any] | str) -> None:
        self.connection.send(message if isinstance(message, str) else json.dumps(message))

    def receive(self, timeout: float = 20.0) -> dict[str, Any]:
        frame = self.connection.recv(timeout=timeout)
        return json.loads(frame) if isinstance(frame, str) else {"binary": frame}

    def receive_op(self, op: str, timeout: float = 20.0) -> dict[str, Any]:
        """The next message with ``op`` (others are skipped)."""
        deadline = time.monotonic() + timeout
        while True:
            message = self.receive(max(0.01, deadline - time.monotonic()))
            if message.get("op") == op:
                return message

    def request(self, message: dict[str, Any], op: str, timeout: float = 20.0) -> dict[str, Any]:
        self.send(message)
        return self.receive_op(op, timeout)

    def close(self) -> None:
        self._stack.close()


def wait_until_discovered(host: str, port: int, topic: str, service: str, node: str, timeout: float = 30.0) -> None:
    """Ask rosapi until the bridge's view of the ROS graph has ``topic``, ``service`` and ``node``:
    discovery is asynchronous, and the tests must not race it."""
    client = RawClient(host, port)
    deadline = time.monotonic() + timeout
    try:
        while time.monotonic() < deadline:
            topics = client.request({"op": "call_service", "service": "/rosapi/topics"}, "service_response")
            services = client.request({"op": "call_service", "service": "/rosapi/services"}, "service_response")
            nodes = client.request({"op": "call_service", "service": "/rosapi/nodes"}, "service_response")
            if (topic in topics["values"]["topics"] and service in services["values"]["services"]
                    and node in nodes["values"]["nodes"]):
                return
            threading.Event().wait(0.05)  # between polls of the bridge's graph view
        raise AssertionError(f"the bridge never saw {topic}, {service} and {node}")
    finally:
        client.close()


def bridge_url(process: Any) -> str:
    """The ws:// URL from the bridge's READY line."""
    for line in process.output:
        match = re.match(r"READY bridge (wss?://\S+)", line)
        if match:
            return match.group(1)
    raise AssertionError(f"no READY line with a URL:\n{process.tail()}")
