"""The same AT server on the EVA arm: an inspection pose is reached and an image captured."""

from __future__ import annotations

import math
from collections.abc import Iterator

import pytest
from at_client import AtClient

from support.at_server import start_stack

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.fixture(scope="module")
def at(ros_env: dict[str, str]) -> Iterator[AtClient]:
    yield from start_stack(ros_env, "eva", 0.0)


def test_inspection_stand_off_reached_and_image_captured(at: AtClient) -> None:
    added = at.call("add_template", class_type="inspection")
    try:
        assert at.register("inspection", added.id, "target", "target/hull_a").success
        plan = at.call("plan_command", type="inspection", id=added.id, trajectory_name="inspect")
        assert plan.success, plan.message
        executed = at.call("execute_command", type="inspection", id=added.id, trajectory_name="inspect")
        assert executed.success, executed.message
        frames = at.fresh_frames()
        target = frames["target/hull_a"].position
        camera = frames["camera/ee_camera"].position
        # The template holds the camera 1.0 m out along the target's normal (z up for hull_a).
        error = math.dist((camera.x, camera.y, camera.z), (target.x, target.y, target.z + 1.0))
        assert error < 0.01, f"camera at {camera}, {error * 1000:.1f} mm from the stand-off point"
        shot = at.capture("ee_camera", "hull_a")
        assert shot.success, shot.message
        assert shot.image.width > 0 and len(shot.image.data) == shot.image.step * shot.image.height
        assert len(set(bytes(shot.image.data))) > 2  # not a blank frame: the panel is in view
        retreat = at.call("plan_command", type="inspection", id=added.id, trajectory_name="retreat", execute=True)
        assert retreat.success, retreat.message
    finally:
        at.call("delete_template", class_type="inspection", id=added.id)
