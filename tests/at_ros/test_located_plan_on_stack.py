"""On a displaced IVA world, the arm pulls the dirty filter out of the cabinet and places it in rack
slot 3 where the registrations say they are, with the planner's collision world still as drawn.

``caretaker up iva --displace 3``: the cabinet is 51 mm and 9° from where the drawings put its
slot, the rack 10 mm and 7.5°. The template is registered to each slot at the simulator's ground
truth (as perception locates it: tests/perception measure that; here it is the planner's part).
Before the planner's world followed registrations (at_ros/registered_world.py), the grasp of the
located filter failed to plan ("grasps 'cdra_filter', but no graspable object of the world" near
the tool: the planner's filter was 5 cm away).
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from at_ros.messages import matrix_from_pose, pose_from_matrix
from at_ros.transforms import invert
from support.bridge_client import BridgeClient
from support.stack import stack_up

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=60)]

AT = "/affordance_template_server"
DIRTY = "CDRA-F-0007"
SEED = 3
#: A plan or a motion beside a loaded suite (the simulation runs as fast as it can).
MOTION_S = 300.0


def _frames(habitat: BridgeClient, *, truth: bool) -> dict[str, np.ndarray]:
    """Where the world model says things are (sim/frames), or where they are (sim/check/frames)."""
    if truth:
        named = habitat.call("/sim/check/frames", "caretaker_sim_msgs/GetFrames", {})["frames"]
    else:
        named = habitat.first("/sim/frames", "caretaker_sim_msgs/NamedPoses")
    return {n: matrix_from_pose(_pose(m)) for n, m in zip(named["names"], named["poses"], strict=True)}


def _pose(message: dict[str, Any]) -> Any:
    from geometry_msgs.msg import Pose

    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (message["position"][k] for k in "xyz")
    o = message["orientation"]
    pose.orientation.x, pose.orientation.y, pose.orientation.z, pose.orientation.w = o["x"], o["y"], o["z"], o["w"]
    return pose


def _pose_dict(matrix: np.ndarray) -> dict[str, Any]:
    pose = pose_from_matrix(matrix)
    return {
        "position": {k: float(getattr(pose.position, k)) for k in "xyz"},
        "orientation": {k: float(getattr(pose.orientation, k)) for k in "xyzw"},
    }


@pytest.fixture(scope="module")
def habitat(ros_env: dict[str, str]) -> Iterator[BridgeClient]:
    with stack_up("iva", ros_env, displace=SEED) as stack:
        client = BridgeClient(stack.url)
        try:
            yield client
        finally:
            client.close()


def test_the_filter_is_pulled_and_placed_where_the_registrations_say(habitat: BridgeClient) -> None:
    drawn, truth = _frames(habitat, truth=False), _frames(habitat, truth=True)
    added = habitat.call(
        f"{AT}/add_template", "affordance_template_msgs/AddAffordanceTemplate", {"class_type": "cdra_filter"}
    )
    assert added["success"], added["message"]
    template = {"type": "cdra_filter", "id": added["id"]}

    def register_and_run(slot: str, trajectory: str) -> None:
        offset = invert(drawn[slot]) @ truth[slot]  # in the slot's frame, as a procedure registers
        assert np.linalg.norm(offset[:3, 3]) > 0.005, f"{slot} is not displaced in seed {SEED}"
        registered = habitat.call(
            f"{AT}/set_object_pose",
            "affordance_template_msgs/SetObjectPose",
            {
                "objects": [
                    {
                        **template,
                        "name": "cdra_filter",
                        "stamped_pose": {"header": {"frame_id": slot}, "pose": _pose_dict(offset)},
                    }
                ]
            },
        )
        assert registered["success"], registered["message"]
        for service, service_type in (("plan_command", "PlanCommand"), ("execute_command", "ExecuteCommand")):
            answer = habitat.call(
                f"{AT}/{service}",
                f"affordance_template_msgs/AffordanceTemplate{service_type}",
                {**template, "trajectory_name": trajectory},
                timeout=MOTION_S,
            )
            assert answer["success"], answer["message"]

    try:
        assert habitat.call("/cdra/unlock_filter", "std_srvs/Trigger", {})["success"]
        register_and_run("cabinet/slot", "grasp_and_pull")
        assert habitat.first("/gripper/held_object", "std_msgs/String")["data"] == DIRTY
        assert habitat.first("/cdra/filter_present", "std_msgs/Bool")["data"] is False

        register_and_run("rack/slot_3", "insert_and_release")
        assert habitat.first("/gripper/held_object", "std_msgs/String")["data"] == ""
        # the simulator puts a seated filter's frame on its slot; a filter resting anywhere else is not in it
        rests = _frames(habitat, truth=True)[f"filter/{DIRTY}"]
        off_mm = 1000 * float(np.linalg.norm(rests[:3, 3] - truth["rack/slot_3"][:3, 3]))
        assert off_mm < 1.0, f"the filter rests {off_mm:.1f} mm from rack slot 3 as it is: not seated there"
    finally:
        habitat.call(
            f"{AT}/delete_template",
            "affordance_template_msgs/DeleteAffordanceTemplate",
            {"class_type": "cdra_filter", "id": added["id"]},
        )
