"""What the 3D view says when it cannot read the robot: the operator's words, never a service name.

A unit test of console/spatial_feed.py alone: its rosbridge client is replaced by one that
fails the way the real client does (``LinkError(service, message)``, rosbridge's own refusal
naming the service); the real link is exercised by test_spatial_on_real_stack.py.
"""

from __future__ import annotations

import asyncio
from typing import Any

import pytest

from console.spatial_feed import SpatialFeed
from console.spatial_link import ViewLink
from rosbridge_wire.client import Endpoint, LinkError


class FailingBridge:
    def __init__(self, message: str | None) -> None:
        self.message = message
        self.asked: list[str] = []

    async def call(self, service: str, request: dict[str, Any]) -> dict[str, Any]:
        self.asked.append(service)
        raise LinkError(service, self.message or f"Service {service} does not exist")


@pytest.mark.parametrize(
    ("message", "said"),
    [
        (None, "could not read the current plan from the robot: the robot side refused the request"),
        ("no answer in time", "could not read the current plan from the robot: no answer in time"),
    ],
)
def test_a_failed_read_is_reported_in_words_and_the_service_only_in_the_log(
    message: str | None, said: str, caplog: pytest.LogCaptureFixture
) -> None:
    feed = SpatialFeed(ViewLink(Endpoint("ws://127.0.0.1:9"), "/"), camera_url="/camera")
    bridge = FailingBridge(message)
    feed.rosbridge = bridge  # type: ignore[assignment]
    feed.active_template = "cdra_filter:0"
    reported: list[dict[str, Any]] = []
    feed._push = reported.append  # type: ignore[method-assign]
    asyncio.run(feed._refresh(plan=True))
    assert bridge.asked == ["/affordance_template_server/get_plan"]
    assert reported[-1] == {"kind": "link", "state": "error", "message": said}
    assert "affordance_template_server" not in said
    assert "/affordance_template_server/get_plan" in caplog.text  # the log keeps what was asked
