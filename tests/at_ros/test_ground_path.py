"""The halt and the 3D view's data as the ground gets them: through the rosbridge server, with a
roslibpy client, from a deployment in ROS namespace /arm2 (every name is relative to it)."""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from pathlib import Path
from urllib.parse import urlparse

import pytest
import roslibpy

from support.stack import robot_parts, write_deployment

pytestmark = [pytest.mark.ros, pytest.mark.slow]

NS = "/arm2"
AT = f"{NS}/affordance_template_server"
DIRTY = "CDRA-F-0007"
TIMEOUT = 60.0


class Ground:
    """A roslibpy client as a ground server uses one: calls with timeouts, latched topics read once."""

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


@pytest.fixture(scope="module")
def ground(ros_env: dict[str, str], tmp_path_factory: pytest.TempPathFactory) -> Iterator[Ground]:
    deployment = write_deployment(
        Path(tmp_path_factory.mktemp("arm2")), "iva", name="arm2", ros={"namespace": NS}, bindings=[], demo=None
    )
    with robot_parts(deployment, ros_env, parts=("sim", "planner", "at-server", "bridge"), time_scale=1.0) as parts:
        client = Ground(parts.bridge_url)
        try:
            yield client
        finally:
            client.close()


def test_the_view_reads_robot_scene_and_plan_through_rosbridge(ground: Ground) -> None:
    for latched in ("robot_description", "sim/visual_world"):
        ground.wait_published(f"{NS}/{latched}")
    description = ground.first(f"{NS}/robot_description", "std_msgs/String")
    assert '<robot name="ur10_gripper"' in description["data"]
    world = ground.first(f"{NS}/sim/visual_world", "caretaker_sim_msgs/VisualWorld")
    assert world["robot_name"] == "ur10" and len(world["arm_joints"]) == 6
    assert f"filter/{DIRTY}" in {o["name"] for o in world["objects"]}

    added = ground.call(
        f"{AT}/add_template", "affordance_template_msgs/AddAffordanceTemplate", {"class_type": "cdra_filter"}
    )
    assert added["success"], added["message"]
    try:
        registered = ground.call(
            f"{AT}/set_object_pose",
            "affordance_template_msgs/SetObjectPose",
            {
                "objects": [
                    {
                        "type": "cdra_filter",
                        "id": added["id"],
                        "name": "cdra_filter",
                        "stamped_pose": {
                            "header": {"frame_id": f"filter/{DIRTY}"},
                            "pose": {"orientation": {"w": 1.0}},
                        },
                    }
                ]
            },
        )
        assert registered["success"], registered["message"]
        status = ground.call(
            f"{AT}/get_template_status",
            "affordance_template_msgs/GetAffordanceTemplateStatus",
            {"name": added["instance"], "trajectory_name": "grasp_and_pull", "frame_id": "world"},
        )
        obj = status["affordance_template_status"][0]["object_info"][0]
        assert (
            obj["type"] == "box"
            and obj["rgba"] == pytest.approx([0.2, 0.9, 0.3, 0.5])
            and obj["controls"] == [True] * 6
        )
        planned = ground.call(
            f"{AT}/plan_command",
            "affordance_template_msgs/AffordanceTemplatePlanCommand",
            {"type": "cdra_filter", "id": added["id"], "trajectory_name": "grasp_and_pull"},
        )
        assert planned["success"], planned["message"]
        plan = ground.call(
            f"{AT}/get_plan", "affordance_template_msgs/GetPlan", {"name": added["instance"], "trajectory_name": ""}
        )
        assert plan["success"] and plan["state"] == "PLANNED" and plan["valid"], plan["message"]
        assert (
            len(plan["waypoint_point_index"]) == 4
            and plan["waypoint_point_index"][-1] == len(plan["trajectory"]["points"]) - 1
        )
        assert plan["end_pose"]["header"]["frame_id"] == "robot_base"
        status_topic = ground.first(f"{AT}/status", "affordance_template_msgs/ServerStatus")
        assert status_topic["plan_id"] == plan["plan_id"]

        # Halt from the ground while it executes: the execution answers halted.
        unlocked = ground.call(f"{NS}/cdra/unlock_filter", "std_srvs/Trigger", {})
        assert unlocked["success"]
        results: dict = {}
        worker = threading.Thread(
            target=lambda: results.update(
                execute=ground.call(
                    f"{AT}/execute_command",
                    "affordance_template_msgs/AffordanceTemplateExecuteCommand",
                    {"type": "cdra_filter", "id": added["id"], "trajectory_name": "grasp_and_pull"},
                    timeout=120,
                )
            )
        )
        worker.start()
        ground.first(
            f"{AT}/status",
            "affordance_template_msgs/ServerStatus",
            lambda m: m["execute_status"] == "EXECUTING" and m["robot_active"],
        )
        halted = ground.call(f"{AT}/halt", "affordance_template_msgs/Halt", {"reason": "ground: Halt pressed"})
        worker.join(120)
        assert halted["success"] and halted["halted"] == added["instance"], halted["message"]
        assert not results["execute"]["success"] and "halted (ground: Halt pressed)" in results["execute"]["message"]
        # The simulation's own halt, for a ground that cannot reach the AT server: nothing moves now.
        direct = ground.call(f"{NS}/robot/halt", "caretaker_sim_msgs/Halt", {"reason": "ground: direct"})
        assert direct["success"] and direct["message"] == "nothing was moving" and not direct["stopped"]
    finally:
        ground.call(
            f"{AT}/delete_template",
            "affordance_template_msgs/DeleteAffordanceTemplate",
            {"class_type": "cdra_filter", "id": added["id"]},
        )
