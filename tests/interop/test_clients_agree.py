"""The same AT commands have the same effect whichever client sends them.

Three real clients drive one real stack (simulation, planner, AT server, rosbridge, each its own
process): the Java PAX plugins through JPype (SysRep commands, as a procedure sends them),
roslibpy, and roslibjs under Node (the AT services directly). Each adds the CDRA filter template,
registers it on the cabinet slot, plans the pull-out, is refused an unknown trajectory, and
deletes the instance; what the AT server then reports must agree.
"""

from __future__ import annotations

import json
import subprocess
import threading
from collections.abc import Iterator
from urllib.parse import urlparse

import pytest

from caretaker.processes import REPO
from support.stack import robot_parts

pytestmark = [pytest.mark.ros, pytest.mark.slow]

AT = "/affordance_template_server"
ZERO_POSE = {"x": 0.0, "y": 0.0, "z": 0.0, "roll": 0.0, "pitch": 0.0, "yaw": 0.0}


@pytest.fixture(scope="module")
def bridge_url(ros_env: dict[str, str]) -> Iterator[str]:
    with robot_parts("iva", ros_env) as stack:
        yield stack.bridge_url


def _roslibpy_call(ros: object, name: str, type_name: str, request: dict) -> dict:
    import roslibpy

    service = roslibpy.Service(ros, f"{AT}/{name}", f"affordance_template_msgs/srv/{type_name}")
    return dict(service.call(roslibpy.ServiceRequest(request), timeout=60))


def via_roslibpy(url: str) -> dict:
    import roslibpy

    parsed = urlparse(url)
    ros = roslibpy.Ros(host=parsed.hostname, port=parsed.port)
    ros.run(30)
    try:
        added = _roslibpy_call(
            ros, "add_template", "AddAffordanceTemplate", {"class_type": "cdra_filter", "hide_waypoints": False}
        )
        registered = _roslibpy_call(
            ros,
            "set_object_pose",
            "SetObjectPose",
            {
                "objects": [
                    {
                        "type": "cdra_filter",
                        "name": "cdra_filter",
                        "id": added["id"],
                        "stamped_pose": {"header": {"frame_id": "cabinet/slot"}, "pose": {"orientation": {"w": 1.0}}},
                    }
                ]
            },
        )
        planned = _roslibpy_call(
            ros,
            "plan_command",
            "AffordanceTemplatePlanCommand",
            {"type": "cdra_filter", "id": added["id"], "trajectory_name": "grasp_and_pull"},
        )
        wrong = _roslibpy_call(
            ros,
            "plan_command",
            "AffordanceTemplatePlanCommand",
            {"type": "cdra_filter", "id": added["id"], "trajectory_name": "no_such_trajectory"},
        )
        running = _roslibpy_call(ros, "get_running", "GetRunningAffordanceTemplates", {})
        deleted = _roslibpy_call(
            ros, "delete_template", "DeleteAffordanceTemplate", {"class_type": "cdra_filter", "id": added["id"]}
        )
    finally:
        ros.close()
    return {
        "instance": added["instance"],
        "added": added["success"],
        "registered": registered["success"],
        "planned": planned["success"],
        "plan_valid": planned["affordance_template_status"]["plan_valid"],
        "unknown_trajectory_refused": not wrong["success"],
        "unknown_trajectory_message": wrong["message"],
        "running_after_add": added["instance"] in running["templates"],
        "deleted": deleted["success"],
    }


def via_roslibjs(url: str) -> dict:
    run = subprocess.run(
        ["node", str(REPO / "tests" / "js" / "at_sequence.mjs"), url],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert run.returncode == 0, run.stderr[-2000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


def via_pax_plugins(url: str) -> dict:
    from pride.pax_host import PaxHost

    with PaxHost(REPO / "sysrep" / "bindings" / "iva.yaml", rosbridge_url=url) as host:
        added = host.execute(
            "affordance_templates",
            "add_affordance_template",
            {"affordance_template": "cdra_filter", "hide_waypoints": False},
        )
        assert added.success, added.message
        instance = added.values["instance"]
        registered = host.execute(
            "affordance_templates",
            "set_display_object_pose",
            {
                "affordance_template": instance,
                "id": added.values["id"],
                "display_object": "cdra_filter",
                "frame": "cabinet/slot",
                **ZERO_POSE,
            },
        )
        # The status topic reports the plan a moment after the command's reply: await that message.
        plan_reported = threading.Event()
        host.add_listener(
            lambda sysrep, item, value: item == "plan_valid" and value.value is True and plan_reported.set()
        )
        planned = host.execute(
            "affordance_templates", "plan_trajectory", {"affordance_template": instance, "trajectory": "grasp_and_pull"}
        )
        plan_valid = plan_reported.wait(10) and host.telemetry("affordance_templates", "plan_valid").value
        wrong = host.execute(
            "affordance_templates",
            "plan_trajectory",
            {"affordance_template": instance, "trajectory": "no_such_trajectory"},
        )
        import roslibpy

        parsed = urlparse(url)
        observer = roslibpy.Ros(host=parsed.hostname, port=parsed.port)
        observer.run(30)
        try:
            running = _roslibpy_call(observer, "get_running", "GetRunningAffordanceTemplates", {})
        finally:
            observer.close()
        deleted = host.execute(
            "affordance_templates",
            "delete_affordance_template",
            {"affordance_template": "cdra_filter", "id": added.values["id"]},
        )
    return {
        "instance": instance,
        "added": added.success,
        "registered": registered.success,
        "planned": planned.success,
        "plan_valid": plan_valid,
        "unknown_trajectory_refused": not wrong.success,
        "unknown_trajectory_message": wrong.message,
        "running_after_add": instance in running["templates"],
        "deleted": deleted.success,
    }


def test_three_clients_have_the_same_effect(bridge_url: str) -> None:
    effects = {
        name: client(bridge_url)
        for name, client in (("pax_plugins", via_pax_plugins), ("roslibpy", via_roslibpy), ("roslibjs", via_roslibjs))
    }
    for name, effect in effects.items():
        assert effect["added"] and effect["registered"] and effect["planned"], (name, effect)
        assert effect["plan_valid"] is True, (name, effect)
        assert effect["running_after_add"] and effect["deleted"], (name, effect)
        assert effect["unknown_trajectory_refused"], (name, effect)
        assert "no_such_trajectory" in effect["unknown_trajectory_message"], (name, effect)
    # every client got the lowest free id again: each deleted what it added
    assert {effect["instance"] for effect in effects.values()} == {effects["roslibpy"]["instance"]}
