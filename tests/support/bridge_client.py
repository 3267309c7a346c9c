"""A roslibpy client of a stack's rosbridge server, as a ground server uses one: calls with
timeouts, latched topics read once."""

from __future__ import annotations

import threading
from collections.abc import Callable
from urllib.parse import urlparse

import roslibpy

__all__ = ["BridgeClient", "TIMEOUT"]

TIMEOUT = 60.0


class BridgeClient:
    """Calls with timeouts, latched topics read once."""

    def __init__(self, url: str) -> None:
        parsed = urlparse(url)
        self.ros = roslibpy.Ros(host=parsed.hostname, port=parsed.port)
        self.ros.run(TIMEOUT)

    def call(self, name: str, service_type: str, request: dict, timeout: float = TIMEOUT) -> dict:
        return dict(
            roslibpy.Service(self.ros, name, service_type).call(roslibpy.ServiceRequest(request), timeout=timeout)
        )

    def wait_published(self, topic: str, timeout: float = TIMEOUT) -> None:
        """Until the bridge's node has discovered a publisher of ``topic``: it subscribes to a
        latched topic as transient local only if it sees the publisher so when the client
        subscribes (graph discovery gives no event to await, so this asks every 0.1 s)."""
        deadline = threading.Event()
        timer = threading.Timer(timeout, deadline.set)
        timer.start()
        try:
            while not self.call("/rosapi/publishers", "rosapi/Publishers", {"topic": topic})["publishers"]:
                assert not deadline.wait(0.1), f"the bridge saw no publisher of {topic} in {timeout} s"
        finally:
            timer.cancel()

    def first(
        self,
        topic: str,
        message_type: str,
        predicate: Callable[[dict], bool] = lambda message: True,
        timeout: float = TIMEOUT,
    ) -> dict:
        """The first message on ``topic`` for which ``predicate`` holds."""
        got: list[dict] = []
        arrived = threading.Event()

        def take(message: dict) -> None:
            if not arrived.is_set() and predicate(message):
                got.append(message)
                arrived.set()

        subscription = roslibpy.Topic(self.ros, topic, message_type)
        subscription.subscribe(take)
        try:
            assert arrived.wait(timeout), f"no such message on {topic} through rosbridge"
        finally:
            subscription.unsubscribe()
        return got[0]

    def close(self) -> None:
        self.ros.close()
