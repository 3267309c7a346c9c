"""The 3D view's data from what the habitat publishes (spatial_world.py): plain data, no ROS.

The real-stack browser test holds the results to the habitat; these pin the rules that test
cannot reach cheaply: the ghost only while a plan is PLANNED, the end pose moved into the world
frame, and bad input refused with the place of the bad value.
"""

from __future__ import annotations

import math
from typing import Any

import pytest

from console.spatial_values import SpatialDataError
from console.spatial_world import compose, plan_from_get_plan, world_document

URDF = (
    '<robot name="r"><link name="base"/><link name="tip"/>'
    '<joint name="j" type="revolute"><parent link="base"/><child link="tip"/></joint></robot>'
)
BASE = {"xyz": [1.0, 2.0, 0.5], "quat": [0.0, 0.0, math.sqrt(0.5), math.sqrt(0.5)]}  # 90 deg about z


def world(**changes: Any) -> dict[str, Any]:
    msg: dict[str, Any] = {
        "scene": "test",
        "robot_name": "r",
        "tool_link": "tip",
        "arm_joints": ["j"],
        "gripper_joints": [],
        "robot_base": {"position": {"x": 0, "y": 0, "z": 0.75}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}},
        "objects": [
            {
                "name": "target/hull_a",
                "pose": {"position": {"x": 1, "y": 0, "z": 0}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}},
                "shapes": [
                    {
                        "type": "cylinder",
                        "radius": 0.1,
                        "length": 0.02,
                        "size": [0, 0, 0],
                        "rgba": [1, 0, 0, 1],
                        "pose": {"position": {"x": 0, "y": 0, "z": 0}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}},
                    }
                ],
            }
        ],
    }
    msg.update(changes)
    return msg


def plan(state: str = "PLANNED", **changes: Any) -> dict[str, Any]:
    answer: dict[str, Any] = {
        "success": True,
        "message": "",
        "plan_id": "p1",
        "state": state,
        "trajectory_name": "t",
        "trajectory": {
            "joint_names": ["j"],
            "points": [
                {"positions": [0.0], "time_from_start": {"sec": 0, "nanosec": 0}},
                {"positions": [1.0], "time_from_start": {"sec": 1, "nanosec": 500_000_000}},
            ],
        },
        "waypoint_names": ["0.0:T:0"],
        "waypoint_point_index": [1],
        "end_effector_poses": ["closed"],
        "end_pose_link": "tip",
        "end_pose": {
            "header": {"frame_id": "robot_base"},
            "pose": {"position": {"x": 0.5, "y": 0, "z": 0}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}},
        },
    }
    answer.update(changes)
    return answer


def test_world_document_places_the_robot_at_its_root_link_and_kinds_objects_by_name() -> None:
    doc = world_document(world(), URDF)
    assert doc["robot"]["base_link"] == "base" and doc["robot"]["base_pose"]["xyz"] == [0, 0, 0.75]
    assert [(o["name"], o["kind"]) for o in doc["objects"]] == [("target/hull_a", "target")]
    assert doc["plan"] is None and doc["templates"] == [] and doc["joints"]["positions"] == {"j": 0.0}


def test_world_document_refuses_bad_input_with_its_place() -> None:
    with pytest.raises(SpatialDataError, match=r"visual_world.objects\[0\].shapes\[0\].type.*unknown shape 'cone'"):
        world_document(
            world(objects=[{"name": "x", "shapes": [{"type": "cone", "pose": world()["robot_base"]}]}]), URDF
        )
    with pytest.raises(SpatialDataError, match="robot_description.data"):
        world_document(world(), "not a urdf")


def test_the_plan_is_shown_while_planned_and_as_commanded_while_executing_with_its_end_in_the_world_frame() -> None:
    update = plan_from_get_plan(plan(), instance="T:0", frames={"robot_base": BASE})
    ghost = update["plan"]
    assert [p["time_from_start"] for p in ghost["points"]] == [0.0, 1.5]
    assert ghost["waypoints"] == [{"name": "0.0:T:0", "point": 1, "end_effector_pose": "closed"}]
    assert ghost["end_pose"]["xyz"] == pytest.approx([1.0, 2.5, 0.5])  # 0.5 m along the base's x, turned 90 deg
    assert ghost["commanded"] is False
    running = plan_from_get_plan(plan("EXECUTING"), instance="T:0", frames={"robot_base": BASE})["plan"]
    assert running["commanded"] is True and running["points"] == ghost["points"]
    for state in ("EXECUTED", "HALTED", "FAILED", "INVALIDATED"):
        assert plan_from_get_plan(plan(state), instance="T:0", frames={}) == {"kind": "plan", "plan": None}


def test_a_plan_with_a_waypoint_past_its_points_is_refused() -> None:
    with pytest.raises(SpatialDataError, match=r"waypoint_point_index\[0\].*point 5 of a plan of 2 points"):
        plan_from_get_plan(plan(waypoint_point_index=[5]), instance="T:0", frames={"robot_base": BASE})


def test_compose_is_the_frame_product() -> None:
    pose = compose(BASE, {"xyz": [0, 1, 0], "quat": [0, 0, math.sqrt(0.5), math.sqrt(0.5)]})
    assert pose["xyz"] == pytest.approx([0.0, 2.0, 0.5])
    assert pose["quat"] == pytest.approx([0, 0, 1, 0], abs=1e-12)


def test_the_camera_image_becomes_a_png_and_bad_images_are_refused() -> None:
    import base64
    import struct
    import zlib

    from console.spatial_camera import CameraImageError, choose_camera, png_from_image

    pixels = bytes([255, 0, 0, 0, 255, 0, 0, 0, 255, 9, 9, 9])  # 2x2 rgb8
    png = png_from_image(
        {"encoding": "rgb8", "width": 2, "height": 2, "step": 6, "data": base64.b64encode(pixels).decode()}
    )
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and struct.unpack(">II", png[16:24]) == (2, 2)
    idat = png.index(b"IDAT")
    length = struct.unpack(">I", png[idat - 4 : idat])[0]
    assert zlib.decompress(png[idat + 4 : idat + 4 + length]) == b"\x00" + pixels[:6] + b"\x00" + pixels[6:]
    with pytest.raises(CameraImageError, match="image.encoding: 'bgr16'"):
        png_from_image({"encoding": "bgr16", "width": 2, "height": 2, "step": 6, "data": ""})
    with pytest.raises(CameraImageError, match="image.data: 3 bytes for 2 rows of 6"):
        png_from_image(
            {"encoding": "rgb8", "width": 2, "height": 2, "step": 6, "data": base64.b64encode(b"abc").decode()}
        )
    assert choose_camera(["tool0", "camera/scene", "camera/ee_camera"], "ee_camera") == "ee_camera"
    assert choose_camera(["tool0", "camera/scene"], "ee_camera") == "scene"
    assert choose_camera(["tool0"], "ee_camera") is None


def test_a_camera_image_with_the_same_pixels_is_not_encoded_or_pushed_again() -> None:
    """An idle robot's camera sends the same image every period: the page is told of a new one only
    when its pixels changed (the page fetches and decodes each it is told of)."""
    import base64

    from console.spatial_feed import SpatialFeed
    from console.spatial_link import ViewLink
    from rosbridge_wire.client import Endpoint

    feed = SpatialFeed(ViewLink(Endpoint("ws://127.0.0.1:9"), "/"), camera_url="/camera")
    pushed: list[dict[str, Any]] = []
    feed._push = pushed.append  # type: ignore[method-assign]

    def image(pixels: bytes, sec: int) -> dict[str, Any]:
        data = base64.b64encode(pixels).decode()
        return {"header": {"stamp": {"sec": sec}}, "encoding": "rgb8", "width": 1, "height": 1, "step": 3, "data": data}

    feed._on_image(image(b"abc", 1))
    feed._on_image(image(b"abc", 2))  # the same pixels a period later
    feed._on_image(image(b"abd", 3))
    assert pushed == [{"kind": "camera", "url": "/camera?seq=1"}, {"kind": "camera", "url": "/camera?seq=2"}]
    feed._on_image({**image(b"abe", 4), "encoding": "bgr16"})  # refused: the last good image stays
    feed._on_image(image(b"abd", 5))
    assert [update.get("url") for update in pushed[2:]] == [None]  # the refusal's report only
