"""perception/locate on a displaced world, against the simulator's ground truth (sim/check/frames).

Real parts: the simulator process renders the markers with pybullet, the perception process
detects them with OpenCV and answers over ROS. Every located pose must be within 5 mm and 1 deg
of where the object really is, at every distance up to 1 m; every image that does not support a
pose must be refused with its reason, never answered with a guess.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from perception_client import PerceptionClient, errors, located
from views import View, views

from at_ros.transforms import angle_between, from_xyz_quat

pytestmark = pytest.mark.slow(seconds=90)

VIEWS = views()


@pytest.mark.parametrize("view", VIEWS, ids=[v.camera for v in VIEWS])
def test_a_located_pose_is_where_the_object_really_is(client: PerceptionClient, view: View) -> None:
    answer = client.locate(view.obj, view.camera)
    assert answer.success, answer.message
    pose = located(answer)
    mm, deg = errors(pose, client.truth(view.obj))
    print(f"{view.camera}: {mm:.2f} mm, {deg:.3f} deg, residual {answer.residual_px:.2f} px, {answer.distance:.2f} m")
    assert mm <= 5.0 and deg <= 1.0, f"{answer.message}: {mm:.2f} mm and {deg:.3f} deg from the truth"
    # The quaternion says the same as roll/pitch/yaw, and the world was displaced from the model.
    assert angle_between(pose, from_xyz_quat((0, 0, 0), (answer.qx, answer.qy, answer.qz, answer.qw))) < 1e-6
    assert answer.offset_mm > 5.0, "the world model and the world agree: is the world displaced?"
    assert answer.frame == "world" and 0.2 < answer.distance < view.distance + 0.3  # to the frame's origin
    assert answer.residual_px <= 1.0


def test_the_last_result_is_latched_for_views(client: PerceptionClient) -> None:
    answer = client.locate("rack/slot_2", "rack_slot_2_60cm_left")
    assert answer.success, answer.message
    result = client.last_result("rack/slot_2")
    assert result.success and list(result.markers) == [3, 4]
    assert result.xyz == pytest.approx([answer.x, answer.y, answer.z])
    assert result.header.frame_id == "world" and result.offset_mm == pytest.approx(answer.offset_mm)


@pytest.fixture
def restored(client: PerceptionClient) -> Iterator[None]:
    """Marker 7 (the cabinet's left one) printed as declared again after the test."""
    try:
        yield
    finally:
        client.print_marker(7, 7)


def test_a_covered_marker_is_refused(client: PerceptionClient, restored: None) -> None:
    client.print_marker(7, -1)
    answer = client.locate("cabinet/slot", "cabinet_slot_60cm_right")
    assert not answer.success
    assert "only marker(s) 8 of 7, 8 are seen" in answer.message, answer.message
    assert (answer.x, answer.y, answer.z, answer.markers) == (0.0, 0.0, 0.0, "")
    result = client.last_result("cabinet/slot")
    assert not result.success and result.message == answer.message


def test_a_marker_of_the_wrong_id_is_refused(client: PerceptionClient, restored: None) -> None:
    client.print_marker(7, 99)
    answer = client.locate("cabinet/slot", "cabinet_slot_60cm_right")
    assert not answer.success
    assert "only marker(s) 8 of 7, 8 are seen" in answer.message, answer.message
    assert "99" in answer.message.split("other markers in view: ")[1].split(", "), answer.message


def test_a_residual_over_the_tolerance_is_refused(client: PerceptionClient) -> None:
    answer = client.locate("cabinet/slot", "cabinet_slot_100cm_left", tolerance_px=0.01)
    assert not answer.success
    assert "over the tolerance of 0.01 px" in answer.message, answer.message


def test_an_object_out_of_view_is_refused(client: PerceptionClient) -> None:
    answer = client.locate("rack/slot_1", "cabinet_slot_60cm_right")
    assert not answer.success
    assert "none of its markers (1, 2) is seen" in answer.message, answer.message


def test_an_object_without_markers_or_an_unknown_camera_is_refused(client: PerceptionClient) -> None:
    answer = client.locate("table", "cabinet_slot_60cm_right")
    assert not answer.success and "no markers are declared on 'table'" in answer.message
    answer = client.locate("cabinet/slot", "no_such_camera")
    assert not answer.success and "no_such_camera" in answer.message
