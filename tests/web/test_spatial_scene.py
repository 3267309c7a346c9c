"""The 3D view's data producer (console.spatial_scene) on the shipped files and on bad input."""

from __future__ import annotations

import copy
import json
import math
import re
from pathlib import Path
from typing import Any

import pytest
import yaml

from console.spatial_scene import scene_document
from console.spatial_updates import PlanSegment, located_update, objects_update, plan_update, templates_update
from console.spatial_values import SpatialDataError

REPO = Path(__file__).resolve().parents[2]


def shipped(name: str) -> tuple[dict[str, Any], str]:
    scene = yaml.safe_load((REPO / "sim" / "scenes" / f"{name}.yaml").read_text())
    urdf = (REPO / "sim" / "robots" / Path(scene["robot"]["urdf"]).name).read_text()
    return scene, urdf


def test_shipped_scenes_make_documents() -> None:
    scene, urdf = shipped("iva")
    doc = json.loads(json.dumps(scene_document(scene, urdf)))  # plain JSON all through
    names = [o["name"] for o in doc["objects"]]
    assert names == [
        "module",
        "table",
        "rack",
        "cabinet",
        "filter/CDRA-F-0012",
        "filter/CDRA-F-0013",
        "filter/CDRA-F-0007",
        "cabinet/latch",
    ]
    cdra = next(o for o in doc["objects"] if o["name"] == "filter/CDRA-F-0007")
    assert cdra["pose"]["xyz"] == [0.15, 0.9, 1.05]  # seated in cabinet/slot
    assert cdra["pose"]["quat"] == pytest.approx([0, 0, math.sin(1.570796 / 2), math.cos(1.570796 / 2)])
    assert cdra["shapes"][1]["pose"]["xyz"] == pytest.approx([-0.13, 0, 0])  # the handle in front of the body
    assert doc["joints"]["positions"]["gripper_left_finger_joint"] == 0.0425  # gripper starts open
    assert doc["robot"]["end_effector_poses"]["closed"] == {
        "gripper_left_finger_joint": 0.0,
        "gripper_right_finger_joint": 0.0,
    }
    assert doc["viewpoint"] == {"eye": [-1.2, -1.1, 1.9], "target": [0.55, 0.25, 0.95], "fov_deg": 70.0}

    scene, urdf = shipped("eva")
    doc = scene_document(scene, urdf)
    impact = next(o for o in doc["objects"] if o["name"] == "target/hull_b")
    assert [s["type"] for s in impact["shapes"]] == ["box", "cylinder"]  # panel and its damage mark
    assert [s["type"] for s in next(o for o in doc["objects"] if o["name"] == "target/hull_a")["shapes"]] == ["box"]
    assert doc["robot"]["end_effector_poses"] == {}


def test_frames_place_moving_objects() -> None:
    scene, urdf = shipped("iva")
    frames = {
        "header": {"frame_id": "world"},
        "names": ["filter/CDRA-F-0007", "cabinet/slot"],
        "poses": [{"position": {"x": 0.1, "y": 0.2, "z": 0.3}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 2}}] * 2,
    }
    doc = scene_document(scene, urdf, frames=frames)
    assert next(o for o in doc["objects"] if o["name"] == "filter/CDRA-F-0007")["pose"] == {
        "xyz": [0.1, 0.2, 0.3],
        "quat": [0, 0, 0, 1.0],
    }


def _broken(path: str, value: Any) -> dict[str, Any]:
    scene, _ = shipped("iva")
    broken = copy.deepcopy(scene)
    *keys, last = path.split(".")
    target: Any = broken
    for k in keys:
        target = target[int(k)] if isinstance(target, list) else target[k]
    if isinstance(target, list):
        target[int(last)] = value
    else:
        target[last] = value
    return broken


@pytest.mark.parametrize(
    ("path", "value", "message"),
    [
        ("robot.arm_joints", "elbow", "scene.robot.arm_joints: expected a list, got str"),
        ("robot.initial_positions", [0.0, 1.0], "scene.robot.initial_positions: expected 6 numbers, got 2"),
        (
            "bodies.1.shapes.0.type",
            "cone",
            "scene.bodies[1].shapes[0].type: unknown shape type 'cone'; expected box or cylinder",
        ),
        ("bodies.0.color", [1, 1, 1, 2], "scene.bodies[0].color: colour components must be within 0..1"),
        ("filters.0.slot", "rack/slot_9", "scene.filters[0].slot: unknown slot 'rack/slot_9'"),
        (
            "bodies.2.shapes.0.size",
            [0.1, float("nan"), 0.1],
            "scene.bodies[2].shapes[0].size[1]: expected a finite number",
        ),
        ("robot.gripper.initial", "half", "scene.robot.gripper.initial: unknown pose 'half'"),
    ],
)
def test_bad_scene_names_the_value(path: str, value: Any, message: str) -> None:
    _, urdf = shipped("iva")
    with pytest.raises(SpatialDataError) as error:
        scene_document(_broken(path, value), urdf)
    assert str(error.value).startswith(message)


def test_bad_feed_input_names_the_value() -> None:
    with pytest.raises(SpatialDataError, match=r"frames.header.frame_id: poses are in 'map'"):
        objects_update({"header": {"frame_id": "map"}, "names": [], "poses": []})
    with pytest.raises(SpatialDataError, match=r"frames.poses\[0\].orientation: the quaternion is zero"):
        objects_update(
            {
                "names": ["a"],
                "poses": [{"position": {"x": 0, "y": 0, "z": 0}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 0}}],
            }
        )
    with pytest.raises(
        SpatialDataError, match=r"statuses\[0\].object_info\[0\].object_pose.header.frame_id: poses must be in 'world'"
    ):
        templates_update(
            [
                {
                    "type": "t",
                    "id": 0,
                    "trajectory_name": "a",
                    "object_info": [
                        {
                            "object_name": "o:0",
                            "object_pose": {"header": {"frame_id": "robot_base"}, "pose": {}},
                            "type": "box",
                            "size": {"x": 1, "y": 1, "z": 1},
                        }
                    ],
                }
            ]
        )
    with pytest.raises(SpatialDataError, match="urdf: expected the text of a URDF file"):
        scene_document(shipped("iva")[0], "not xml")


def _segment(label: str, times: list[float], positions: list[list[float]], pose: str = "") -> PlanSegment:
    points = [
        {"positions": p, "time_from_start": {"sec": int(t), "nanosec": round((t - int(t)) * 1e9)}}
        for t, p in zip(times, positions, strict=True)
    ]
    return PlanSegment(label, {"joint_names": ["b", "a"], "points": points}, pose)


def test_plan_segments_join_into_one_path() -> None:
    update = plan_update(
        instance="T:0",
        trajectory="go",
        joint_names=["a", "b"],
        start_positions=[0.0, 0.0],
        segments=[
            _segment("0.0:T:0", [0.5, 1.0], [[1, 2], [2, 4]], "open"),
            _segment("0.1:T:0", [], [], "closed"),
            _segment("0.2:T:0", [0.0, 2.0], [[2, 4], [3, 6]]),
        ],
    )
    plan = update["plan"]
    assert [p["time_from_start"] for p in plan["points"]] == [0.0, 0.5, 1.0, 3.0]
    assert plan["points"][-1]["positions"] == [6.0, 3.0]  # by name: the segment lists b before a
    assert [w["point"] for w in plan["waypoints"]] == [2, 2, 3]  # closing the gripper moves no joint
    with pytest.raises(
        SpatialDataError,
        match=r"plan.segments\[1\].trajectory.points\[0\].time_from_start: time 0.500 s does not increase",
    ):
        plan_update(
            instance="T:0",
            trajectory="go",
            joint_names=["a", "b"],
            start_positions=[0, 0],
            segments=[_segment("x", [1.0], [[1, 1]]), _segment("y", [-0.5], [[2, 2]])],
        )
    with pytest.raises(SpatialDataError, match="unknown joint 'b'"):
        plan_update(
            instance="T:0",
            trajectory="go",
            joint_names=["a"],
            start_positions=[0],
            segments=[_segment("x", [1.0], [[1, 1]])],
        )


def _located(**changes: Any) -> dict[str, Any]:
    """rosbridge JSON of a LocateResult: target/hull_a found 2 cm along its own x, turned 90 deg about z."""
    half = math.sqrt(0.5)
    result: dict[str, Any] = {
        "header": {"stamp": {"sec": 12, "nanosec": 500_000_000}, "frame_id": "target/hull_a"},
        "object": "target/hull_a",
        "camera": "ee_camera",
        "success": True,
        "message": "target/hull_a located",
        "xyz": [0.02, 0.0, 0.0],
        "quaternion": [0.0, 0.0, half, half],
        "residual_px": 0.31,
        "markers": [30, 31],
        "offset_mm": 20.0,
        "offset_deg": 90.0,
    }
    result.update(changes)
    return result


def test_a_locate_result_becomes_a_pose_in_the_document_frame() -> None:
    half = math.sqrt(0.5)
    # the named frame at (1, 2, 3), turned 90 deg about z: its x is the world's y
    frames = {"target/hull_a": {"xyz": [1.0, 2.0, 3.0], "quat": [0.0, 0.0, half, half]}}
    located = located_update(_located(), frames)["located"]
    assert located["success"] and located["markers"] == [30, 31] and located["stamp"] == 12.5
    assert located["pose"]["xyz"] == pytest.approx([1.0, 2.02, 3.0])
    assert located["pose"]["quat"] == pytest.approx([0.0, 0.0, 1.0, 0.0], abs=1e-12)  # 180 deg about z
    in_world = located_update(_located(header={"frame_id": "world"}), {})["located"]
    assert in_world["pose"]["xyz"] == pytest.approx([0.02, 0.0, 0.0])
    refused = located_update(_located(success=False, message="none of its markers (36, 37) is seen"), {})
    assert refused["located"]["pose"] is None and "is seen" in refused["located"]["message"]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"header": {"frame_id": "robot_base"}}, "located.header.frame_id: the pose is in 'robot_base'"),
        ({"success": "yes"}, "located.success: expected true or false"),
        ({"quaternion": [0, 0, 0, 0]}, "located.quaternion: the quaternion is zero"),
        ({"xyz": [1, 2]}, "located.xyz: expected 3 numbers"),
        ({"markers": ["x"]}, "located.markers[0]"),
        ({"object": 7}, "located.object"),
    ],
)
def test_a_bad_locate_result_names_the_value(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(SpatialDataError, match=re.escape(message)):
        located_update(_located(**changes), {"target/hull_a": {"xyz": [0, 0, 0], "quat": [0, 0, 0, 1]}})
