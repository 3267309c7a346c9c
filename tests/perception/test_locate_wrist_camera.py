"""A camera on the arm: the UR10's wrist camera locates the cabinet slot of a displaced world.

Its pose when the image is taken comes from the arm's kinematics (``/camera/capture`` answers
it), its calibration from ``camera/wrist_camera/camera_info``. The arm starts with the camera
0.6 m from the cabinet's markers (views.WRIST_VIEW, by IK on the scene's robot).
"""

from __future__ import annotations

import pytest
from perception_client import PerceptionClient, errors, located
from views import WRIST_VIEW

pytestmark = pytest.mark.slow(seconds=30)

ARM = WRIST_VIEW  # the module's stack starts the arm looking there (conftest.py)


@pytest.mark.parametrize("frame", ["world", "robot_base"])
def test_the_wrist_camera_locates_the_cabinet_slot(client: PerceptionClient, frame: str) -> None:
    """In the world, and in the frame the robot plans in (what set_display_object_pose takes)."""
    answer = client.locate("cabinet/slot", "wrist_camera", frame=frame)
    assert answer.success, answer.message
    mm, deg = errors(located(answer), client.truth("cabinet/slot", frame))
    print(f"wrist_camera, {frame}: {mm:.2f} mm, {deg:.3f} deg, residual {answer.residual_px:.2f} px")
    assert mm <= 5.0 and deg <= 1.0, f"{answer.message}: {mm:.2f} mm and {deg:.3f} deg from the truth"
    assert answer.markers == "7,8" and answer.frame == frame
