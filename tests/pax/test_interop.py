"""The PAX chain end to end: PaxHost (JPype) → Java plugins → rosbridge (`caretaker bridge`) →
the real AT server, planner and simulation of the IVA robot, each a real process.

Each AT command sent through the chain is compared with the same request made directly with
rclpy on a twin template instance: both must leave the server in the same state. The module's
last test kills the AT server and restarts it under the same PaxHost.
"""

from __future__ import annotations

import math
import queue
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from pax_probe import RobotProbe
from pax_stack import BINDINGS, REPO, Stack

from pride.pax_host import PaxHost
from pride.systems import CommandResult, TelemetryValue

pytestmark = [pytest.mark.ros, pytest.mark.slow]

AT = "affordance_templates"
DIRTY = "CDRA-F-0007"
STALE_AFTER = 1.5
ZERO_POSE = dict(x=0.0, y=0.0, z=0.0, roll=0.0, pitch=0.0, yaw=0.0)


@pytest.fixture(scope="module")
def binding(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The shipped IVA binding, moved out of the checkout, with a short stale_after for the kill test."""
    text = (BINDINGS / "iva.yaml").read_text()
    text = text.replace("stale_after: 2.0", f"stale_after: {STALE_AFTER}")
    text = text.replace("sysrep: ../", f"sysrep: {REPO / 'sysrep'}/")
    path = tmp_path_factory.mktemp("binding") / "iva_test.yaml"
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def host(stack: Stack, binding: Path) -> PaxHost:
    pax = PaxHost(binding, rosbridge_url=stack.bridge_url)
    yield pax
    pax.close()


@pytest.fixture(scope="module")
def probe(stack: Stack) -> RobotProbe:
    robot = RobotProbe()
    robot.wait_for(
        lambda: robot.status is not None and robot.status.planner_node_active, 60.0, "AT status with planner"
    )
    yield robot
    robot.close()


class Changes:
    """Telemetry changes reported to one PaxHost listener: awaited by event, never by sleeping."""

    def __init__(self, host: PaxHost) -> None:
        self.host = host
        self.events: queue.Queue[tuple[str, str, TelemetryValue]] = queue.Queue()
        self.condition = threading.Condition()
        host.add_listener(self.listener_callback)

    def listener_callback(self, sysrep: str, item: str, value: TelemetryValue) -> None:
        self.events.put((sysrep, item, value))
        with self.condition:
            self.condition.notify_all()

    def forget(self) -> None:
        """Drop the changes seen so far, so :meth:`wait` sees only what happens next."""
        while not self.events.empty():
            self.events.get_nowait()

    def wait(self, sysrep: str, item: str, value: object, stale: bool, timeout: float) -> float:
        """Block until ``item`` reports ``value`` with ``stale``; the monotonic time it did."""
        deadline = time.monotonic() + timeout
        seen: list[TelemetryValue] = []
        while (remaining := deadline - time.monotonic()) > 0:
            try:
                got = self.events.get(timeout=remaining)
            except queue.Empty:
                break
            if got[:2] == (sysrep, item):
                if got[2].value == value and got[2].stale == stale:
                    return time.monotonic()
                seen.append(got[2])
        raise TimeoutError(
            f"{sysrep}.{item} did not become {value!r} (stale={stale}) within {timeout} s;"
            f" it reported {seen[-5:]}, now {self.host.telemetry(sysrep, item)} at {time.time():.3f}"
        )

    def until(self, predicate: Callable[[], bool], what: str, timeout: float = 10.0) -> None:
        """Block until ``predicate()`` (a read of PaxHost telemetry) holds, re-checking on each change."""
        deadline = time.monotonic() + timeout
        with self.condition:
            while not predicate():
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise TimeoutError(f"{what} not seen within {timeout} s")
                self.condition.wait(remaining)


@pytest.fixture(scope="module")
def changes(host: PaxHost) -> Changes:
    return Changes(host)


def _positions(status_response: Any) -> list[float]:
    """Every object and waypoint position of a template status, in the robot frame, as x, y, z, x, ..."""
    status = status_response.affordance_template_status[0]
    points = [o.object_pose.pose.position for o in status.object_info]
    points += [p.pose.position for w in status.waypoint_info for p in w.waypoint_poses]
    return [c for p in points for c in (p.x, p.y, p.z)]


def _fresh(host: PaxHost, sysrep: str, item: str) -> object:
    """The item's value when it is fresh; None while it is stale."""
    value = host.telemetry(sysrep, item)
    return None if value.stale else value.value


def test_sysreps_of_the_binding(host: PaxHost) -> None:
    assert host.system_ids() == {AT, "cdra", "gripper", "camera", "perception"}


def test_telemetry_follows_the_status_topic(host: PaxHost, probe: RobotProbe) -> None:
    probe.wait_for(lambda: probe.status is not None, 30.0, "a status")
    deadline = time.monotonic() + 30.0
    items = (
        "robot_active",
        "planner_node_active",
        "affordance_template_server_active",
        "execute_status",
        "plan_status",
        "plan_valid",
    )
    while True:
        status = probe.status
        seen = {item: host.telemetry(AT, item) for item in items}
        expected = {item: getattr(status, item) for item in items}
        if {k: v.value for k, v in seen.items()} == expected or time.monotonic() > deadline:
            break
        probe.wait_for(lambda status=status: probe.status is not status, 5.0, "the next status")
    assert {k: v.value for k, v in seen.items()} == expected
    assert not any(v.stale for v in seen.values())
    assert all(abs(v.timestamp - time.time()) < 60 for v in seen.values())


def test_every_at_command_has_the_effect_of_the_direct_call(host: PaxHost, probe: RobotProbe, changes: Changes) -> None:
    added = host.execute(AT, "add_affordance_template", {"affordance_template": "cdra_filter", "hide_waypoints": False})
    assert added.success, added.message
    pax_id = added.values["id"]
    assert added.values["instance"] == f"cdra_filter:{pax_id}"
    twin = probe.call("add_template", class_type="cdra_filter")
    try:
        assert {added.values["instance"], twin.instance} <= set(probe.call("get_running").templates)
        pax = f"cdra_filter:{pax_id}"

        # set_display_object_pose: register both on the dirty filter in the cabinet.
        registered = host.execute(
            AT,
            "set_display_object_pose",
            {
                "affordance_template": pax,
                "id": -1,
                "display_object": "cdra_filter",
                "frame": f"filter/{DIRTY}",
                **ZERO_POSE,
            },
        )
        assert registered.success, registered.message
        assert probe.register("cdra_filter", twin.id, "cdra_filter", f"filter/{DIRTY}").success

        # set_waypoint_pose: move waypoint 0 of both by the same offset in its display object's frame.
        offset = dict(x=-0.3, y=0.0, z=0.05, roll=0.0, pitch=0.0, yaw=math.pi / 2)
        moved = host.execute(
            AT,
            "set_waypoint_pose",
            {
                "affordance_template": "cdra_filter",
                "id": pax_id,
                "trajectory": "grasp_and_pull",
                "waypoint_id": 0,
                "ee_name": "",
                "frame_id": "",
                **offset,
            },
        )
        assert moved.success, moved.message
        from geometry_msgs.msg import PoseStamped

        pose = PoseStamped()
        pose.pose.position.x, pose.pose.position.z = -0.3, 0.05
        pose.pose.orientation.z, pose.pose.orientation.w = math.sin(math.pi / 4), math.cos(math.pi / 4)
        direct = probe.call(
            "set_waypoint_pose",
            type="cdra_filter",
            id=twin.id,
            trajectory_name="grasp_and_pull",
            waypoint_id=0,
            end_effector="",
            pose=pose,
        )
        assert direct.success, direct.message
        ours = probe.call("get_template_status", name=pax, trajectory_name="grasp_and_pull")
        theirs = probe.call("get_template_status", name=twin.instance, trajectory_name="grasp_and_pull")
        assert _positions(ours) == pytest.approx(_positions(theirs), abs=1e-6)

        # Ambiguity is a failure with a message, never a guess.
        ambiguous = host.execute(
            AT, "plan_trajectory", {"affordance_template": "cdra_filter", "trajectory": "grasp_and_pull"}
        )
        assert not ambiguous.success and "ambiguous" in ambiguous.message and twin.instance in ambiguous.message
        unknown = host.execute(AT, "plan_trajectory", {"affordance_template": "hatch", "trajectory": "open"})
        assert not unknown.success and "no running instance of template 'hatch'" in unknown.message
        assert probe.call("delete_template", class_type="cdra_filter", id=twin.id).success

        # plan_trajectory by type (now the only instance); the server's own failure comes back verbatim.
        bad = host.execute(
            AT, "plan_trajectory", {"affordance_template": "cdra_filter", "trajectory": "no_such_trajectory"}
        )
        assert not bad.success and "no_such_trajectory" in bad.message
        planned = host.execute(
            AT, "plan_trajectory", {"affordance_template": "cdra_filter", "trajectory": "grasp_and_pull"}
        )
        assert planned.success, planned.message
        end_pose = planned.values.pop("end_pose")
        assert planned.values == {
            "plan_status": "PLANNED",
            "plan_valid": True,
            "instance": pax,
            "end_pose_frame": "robot_base",
        }
        assert len(end_pose) == 6 and all(isinstance(v, float) for v in end_pose)
        probe.wait_for(lambda: probe.status.plan_valid, 10.0, "plan_valid in the status")

        # The CDRA bay through the ROS-convention plugin: unlock, and the latch telemetry follows.
        unlocked = host.execute("cdra", "unlock_filter", {})
        assert unlocked.success, unlocked.message
        probe.wait_for(lambda: probe.filter_locked is False, 10.0, "/cdra/filter_locked false")
        changes.until(
            lambda: host.telemetry("cdra", "filter_locked").value is False, "cdra.filter_locked false via PAX"
        )

        executed = host.execute(AT, "execute_plan", {"affordance_template": pax, "trajectory": "grasp_and_pull"})
        assert executed.success, executed.message
        assert executed.values["execute_status"] == "SUCCEEDED"
        probe.wait_for(lambda: probe.held_object == DIRTY, 10.0, "the dirty filter in the gripper")
        changes.until(
            lambda: host.telemetry(AT, "execute_status").value == "SUCCEEDED", "execute_status SUCCEEDED via PAX"
        )
        again = host.execute(AT, "execute_plan", {"affordance_template": pax, "trajectory": "grasp_and_pull"})
        assert not again.success and again.message  # a plan runs once: the server says so, PAX repeats it
    finally:
        running = set(probe.call("get_running").templates)
        if twin.instance in running:
            probe.call("delete_template", class_type="cdra_filter", id=twin.id)
    deleted = host.execute(AT, "delete_affordance_template", {"affordance_template": "cdra_filter", "id": pax_id})
    assert deleted.success, deleted.message
    assert f"cdra_filter:{pax_id}" not in probe.call("get_running").templates


def test_camera_capture_by_convention(host: PaxHost, tmp_path: Path) -> None:
    captured = host.execute("camera", "capture", {"camera": "scene", "label": "pax_test"})
    assert captured.success, captured.message
    saved = Path(captured.values["path"])
    assert saved.is_file() and saved.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    saved.unlink()
    wrong = host.execute("camera", "capture", {"camera": "no_such_camera", "label": ""})
    assert not wrong.success and "no_such_camera" in wrong.message


def _retry_while(reason: str, command: Callable[[], CommandResult], timeout: float = 30.0) -> CommandResult:
    """Repeat a command while it fails for a transient ``reason`` (a process still starting up)."""
    deadline = time.monotonic() + timeout
    while True:
        result = command()
        if result.success or reason not in result.message or time.monotonic() > deadline:
            return result
        threading.Event().wait(0.2)


def test_killing_the_at_server_marks_values_stale_and_a_restart_recovers(
    host: PaxHost, stack: Stack, changes: Changes
) -> None:
    changes.until(lambda: host.telemetry(AT, "affordance_template_server_active").value is True, "server active")
    changes.forget()
    killed_at = time.monotonic()
    stack.processes["at-server"].kill()
    noticed_at = changes.wait(AT, "affordance_template_server_active", False, stale=False, timeout=STALE_AFTER + 10.0)
    print(f"server loss noticed {noticed_at - killed_at:.2f} s after the kill (stale_after {STALE_AFTER} s)")
    for item in ("robot_active", "planner_node_active", "execute_status", "plan_status", "plan_valid"):
        assert host.telemetry(AT, item).stale, item
    assert host.telemetry(AT, "affordance_template_server_active").value is False
    refused = host.execute(
        AT, "add_affordance_template", {"affordance_template": "ready_pose", "hide_waypoints": False}
    )
    assert not refused.success and refused.message  # the server is gone: a failure, never a fake success

    stack.start_part("at-server")
    changes.wait(AT, "affordance_template_server_active", True, stale=False, timeout=60.0)
    changes.until(
        lambda: not any(host.telemetry(AT, i).stale for i in ("plan_status", "robot_active")), "fresh values again"
    )
    # The new server may answer before it has heard /sim/frames; it then refuses with a reason.
    # Retry on that answer until it accepts (same JVM, same connection throughout).
    added = _retry_while(
        "no frames received",
        lambda: host.execute(
            AT, "add_affordance_template", {"affordance_template": "ready_pose", "hide_waypoints": False}
        ),
    )
    assert added.success, added.message
    assert host.execute(
        AT, "delete_affordance_template", {"affordance_template": added.values["instance"], "id": -1}
    ).success


def test_a_restarted_rosbridge_is_reconnected_and_resubscribed(host: PaxHost, stack: Stack, changes: Changes) -> None:
    # The server must be known first (run alone, this test starts before any status arrived).
    changes.until(lambda: _fresh(host, AT, "affordance_template_server_active") is True, "the AT server active", 60.0)
    changes.forget()
    stack.processes["bridge"].kill()
    # Without a connection nothing is known about the AT server: its values go stale, none turns false.
    changes.wait(AT, "affordance_template_server_active", True, stale=True, timeout=STALE_AFTER + 10.0)
    changes.until(lambda: host.telemetry("cdra", "filter_locked").stale, "cdra values stale once the bridge is gone")
    down = host.execute("cdra", "lock_filter", {})
    assert not down.success and "not connected" in down.message, down.message

    stack.start_part("bridge")  # on the port it had
    # Same JVM, same PaxHost: the client reconnects and re-sends its subscriptions by itself.
    changes.wait(AT, "affordance_template_server_active", True, stale=False, timeout=30.0)
    # A new bridge may not have discovered the simulation's services yet: it says so; retry on that.
    locked = _retry_while("does not exist", lambda: host.execute("cdra", "lock_filter", {}))
    assert locked.success, locked.message
    # The /cdra subscriptions were re-sent: the latch's new state arrives fresh.
    changes.until(lambda: _fresh(host, "cdra", "filter_locked") is True, "cdra.filter_locked true and fresh")
