"""A motion the run sent is drawn as commanded from the moment it is sent, not a light time later;
perception's result is shown only once the run located something itself (the latched one before
is another run's).

A unit test of console/spatial_feed.py alone: its rosbridge client is replaced by one that
answers ``get_plan`` as the AT server does; the real link is exercised by
tests/flight/test_console_over_the_link.py (the ground run over the 1.3 s link).
"""

from __future__ import annotations

import asyncio
from typing import Any

from console.spatial_feed import SpatialFeed
from console.spatial_link import ViewLink
from rosbridge_wire.client import Endpoint


def _get_plan(state: str, trajectory: str = "ready") -> dict[str, Any]:
    return {
        "success": True,
        "state": state,
        "trajectory_name": trajectory,
        "end_pose_link": "tool0",
        "trajectory": {
            "joint_names": ["shoulder_pan_joint"],
            "points": [
                {"positions": [0.0], "time_from_start": {"sec": 0, "nanosec": 0}},
                {"positions": [0.5], "time_from_start": {"sec": 2, "nanosec": 0}},
            ],
        },
    }


class PlanBridge:
    """Answers get_plan with the state the test sets."""

    def __init__(self) -> None:
        self.answer = _get_plan("PLANNED")
        self.asked = 0

    async def call(self, service: str, request: dict[str, Any]) -> dict[str, Any]:
        assert service == "/affordance_template_server/get_plan", service
        self.asked += 1
        return self.answer


def test_the_plan_sent_is_commanded_until_its_answer_and_another_plan_is_not() -> None:
    async def walk() -> None:
        feed = SpatialFeed(ViewLink(Endpoint("ws://127.0.0.1:9"), "/"), camera_url="/camera")
        bridge = PlanBridge()
        feed.rosbridge = bridge  # type: ignore[assignment]
        pushed: list[dict[str, Any]] = []
        feed._push = pushed.append  # type: ignore[method-assign]
        feed.active_template = "ready_pose:0"
        await feed._ask_plan()
        assert pushed[-1]["plan"]["commanded"] is False  # planned: the ghost

        feed.command_sent("ready_pose:0", "ready")
        assert pushed[-1]["plan"]["commanded"] is True and pushed[-1]["plan"]["trajectory"] == "ready"
        await feed._ask_plan()  # the habitat still says PLANNED (its news is a light time old)
        assert pushed[-1]["plan"]["commanded"] is True

        bridge.answer = {"success": True, "state": "EXECUTED"}
        asked = bridge.asked
        feed.command_ended()
        assert feed._refreshing is not None
        await feed._refreshing
        assert bridge.asked == asked + 1 and pushed[-1] == {"kind": "plan", "plan": None}
        bridge.answer = _get_plan("PLANNED")
        await feed._ask_plan()  # planned again after the motion: the ghost, not commanded
        assert pushed[-1]["plan"]["commanded"] is False

    asyncio.run(walk())


def test_a_motion_sent_before_its_plan_came_is_drawn_commanded_even_if_already_executed_there() -> None:
    """Across the light time the run sends a short motion before the feed has the plan (its
    refresh is a round trip behind) and the habitat has executed it before the feed's question
    arrives: the path is still the one the arm drawn (a light time old) follows, until the
    command's answer comes down."""

    async def walk() -> None:
        feed = SpatialFeed(ViewLink(Endpoint("ws://127.0.0.1:9"), "/"), camera_url="/camera")
        bridge = PlanBridge()
        asked: list[dict[str, Any]] = []
        answer_of = bridge.call

        async def call(service: str, request: dict[str, Any]) -> dict[str, Any]:
            asked.append(request)
            return await answer_of(service, request)

        bridge.call = call  # type: ignore[method-assign]
        feed.rosbridge = bridge  # type: ignore[assignment]
        pushed: list[dict[str, Any]] = []
        feed._push = pushed.append  # type: ignore[method-assign]
        feed.active_template = "ready_pose:0"  # the status still names the last instance
        bridge.answer = _get_plan("EXECUTED", trajectory="approach")

        feed.command_sent("cdra_filter:0", "approach")
        assert pushed[-1] == {"kind": "plan", "plan": None}  # nothing to draw yet: asked at once
        assert feed._refreshing is not None
        await feed._refreshing
        assert asked == [{"name": "cdra_filter:0", "trajectory_name": "approach"}]
        plan = pushed[-1]["plan"]
        assert plan["instance"] == "cdra_filter:0" and plan["trajectory"] == "approach" and plan["commanded"] is True

        feed.command_ended()  # the answer came down: the habitat's state is shown again
        await feed._refreshing
        assert asked[-1] == {"name": "ready_pose:0", "trajectory_name": ""}
        assert pushed[-1] == {"kind": "plan", "plan": None}

    asyncio.run(walk())


def test_a_perception_result_from_before_the_run_located_anything_is_not_shown() -> None:
    """``perception/last_result`` is latched: a new run's feed is handed the previous run's locate
    as it subscribes. The view shows only this run's: results count once the run sent a locate."""
    feed = SpatialFeed(ViewLink(Endpoint("ws://127.0.0.1:9"), "/"), camera_url="/camera")
    pushed: list[dict[str, Any]] = []
    feed._push = pushed.append  # type: ignore[method-assign]
    feed.frame_poses = {"world": {"xyz": [0.0, 0.0, 0.0], "quat": [0.0, 0.0, 0.0, 1.0]}}
    result = {
        "header": {"stamp": {"sec": 12, "nanosec": 0}, "frame_id": "world"},
        "object": "cabinet/slot",
        "camera": "wrist_camera",
        "success": True,
        "message": "cabinet/slot located",
        "xyz": [0.5, 0.0, 1.0],
        "quaternion": [0.0, 0.0, 0.0, 1.0],
        "offset_mm": 0.6552,
    }
    feed._on_located(result)  # the previous run's, latched
    assert pushed == [] and feed.located is None and feed.watch().pending == {}
    feed.locate_sent()
    feed._on_located({**result, "offset_mm": 1.5})  # this run's own locate
    assert [update["located"]["offset_mm"] for update in pushed] == [1.5]
