"""The cdra_filter template's looks put the UR10's wrist camera where it locates each IVA object.

What the filter change will do before each registration (as eva_inspect_target.xml does for a
hull target): the template registered where the world model has the object, a ``look_*``
trajectory planned and executed by the AT server, the object located by perception in the wrist
camera's image, and the template registered where it was found. Here on the real robot side
(simulation, perception, planner, AT server; one stack per world), undisplaced and displaced
(``--displace``: the rack and the cabinet, with their slots and the filters in them, up to 4 cm
and 8 deg off the drawings), each located pose against the simulator's ground truth.

The looks (one JOINT waypoint each, relative to the ``cdra_filter`` display object, x into the
slot, z up; the camera 0.065 m beside and 0.095 m behind the tool point, along its axis):

- ``look_above``: 0.55 m from the markers above a slot (the cabinet housing's 7 and 8, 30 cm
  apart), 10 deg to the side and 15 deg above them, the image's long side horizontal;
- ``look_below``: 0.6 m from the markers below a slot (the rack stand's two, 25 cm apart), 6 deg
  to the side and 18 deg above, the image's long side vertical;
- ``look_filter``: 0.22 m from a seated filter's face, straight on and 40 deg above it. Its two
  3.6 cm markers sit beside a handle that hides one from more than a few degrees to the side, so
  it is looked at square-on: from the slot as located, never from the drawings (a slot turned
  7 deg hides a marker; a filter seen from 0.45-0.55 m is found to 1.5-4 deg only).

One pose cannot serve both slots: the cabinet's markers are above its slot and 40 cm wide, the
rack's below and 35 cm tall; one image holds either only from 0.7-0.8 m, and from there the tool
is out of the arm's reach near its base at the cabinet or at rack/slot_3 (the planner's IK), or
the cabinet's markers run off the image. What is located from where:

- ``cabinet/slot`` from ``look_above`` at the cabinet slot as drawn (serves the dirty filter's
  grasp and the clean filter's insertion);
- ``filter/CDRA-F-0007`` from ``look_filter`` at the cabinet slot as located;
- ``rack/slot_3`` from ``look_below`` at the slot as drawn (the dirty filter's insertion);
- ``rack/slot_1`` from ``look_below`` at the slot as drawn, then ``filter/CDRA-F-0012`` from
  ``look_filter`` at the slot as located (the clean filter's grasp).

The looks keep the gripper open (``ee_pose`` 0): they are for an empty gripper, before a grasp.

Then the arm goes on from what was located, as the filter change will: the dirty filter is
registered where its markers put it, pulled out of the cabinet, registered into rack slot 3 where
that was located and placed there. The planner's collision world stays as drawn; it follows the
registrations (at_ros/registered_world.py; without that, a grasp of the located filter found no
filter near the tool: the planner's was 5 cm away).
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest
from geometry_msgs.msg import Pose
from perception_client import PerceptionClient, errors, located
from views import frame_pose

from at_ros.transforms import from_xyz_rpy
from sim.scene import load_scene
from support.stack import robot_parts, write_deployment

if "at_client" not in sys.modules:  # tests/at_ros/at_client.py, when that folder's tests did not load it
    sys.path.append(str(Path(__file__).resolve().parents[1] / "at_ros"))
from at_client import AtClient

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=240)]

PARTS = ("sim", "perception", "planner", "at-server")

DIRTY = "filter/CDRA-F-0007"
#: A plan, a motion or the arm coming to rest beside a loaded suite.
MOTION_S = 300.0
#: (trajectory, frame the template is registered at, object located, registered where it was
#: located), in the filter change's order: what the dirty filter's removal and placing need, before
#: the grasp (a look opens the gripper); the clean filter's, after the dirty filter is placed.
LOOKS_BEFORE_THE_PULL = [
    ("look_above", "cabinet/slot", "cabinet/slot", False),
    ("look_filter", "cabinet/slot", DIRTY, True),
    ("look_below", "rack/slot_3", "rack/slot_3", False),
]
LOOKS_AFTER_THE_PLACING = [
    ("look_below", "rack/slot_1", "rack/slot_1", False),
    ("look_filter", "rack/slot_1", "filter/CDRA-F-0012", True),
]


def _pose(answer: object) -> Pose:
    """A locate answer's pose (in the frame it was asked in) as a registration takes it."""
    pose = Pose()
    pose.position.x, pose.position.y, pose.position.z = (float(getattr(answer, k)) for k in ("x", "y", "z"))
    q = pose.orientation
    q.x, q.y, q.z, q.w = (float(getattr(answer, k)) for k in ("qx", "qy", "qz", "qw"))
    return pose


@pytest.mark.parametrize("seed", [3, 17, 42])
def test_each_look_locates_its_object_and_the_dirty_filter_is_moved_where_they_were_found(
    seed: int, tmp_path: Path, ros_env: dict[str, str]
) -> None:
    scene = load_scene("iva")
    deployment = write_deployment(tmp_path, "iva", displace=seed)
    with robot_parts(deployment, ros_env, parts=PARTS):
        at, perception = AtClient(), PerceptionClient()
        try:
            at.wait_for(
                lambda: at.status is not None and at.status.planner_node_active and bool(at.frames),
                60.0,
                "server status with an active planner",
            )
            added = at.call("add_template", class_type="cdra_filter")
            assert added.success, added.message
            found: dict[str, Pose] = {}  # where each object was located, in its frame as drawn
            failures: list[str] = []

            def register_and_move(trajectory: str, frame: str, where: Pose | None) -> None:
                registered = at.register("cdra_filter", added.id, "cdra_filter", frame, where)
                assert registered.success, registered.message
                for service in ("plan_command", "execute_command"):
                    answer = at.call(
                        service, type="cdra_filter", id=added.id, trajectory_name=trajectory, call_timeout=MOTION_S
                    )
                    assert answer.success, (
                        f"{trajectory} at {frame}{'' if where is None else ' as located'}: {answer.message}"
                    )

            def look_and_locate(trajectory: str, frame: str, obj: str, at_located: bool) -> None:
                register_and_move(trajectory, frame, found[frame] if at_located else None)  # None: as drawn
                at.fresh_frames(timeout=MOTION_S)  # the arm at rest where the look put it
                answer = perception.locate(obj, "wrist_camera", frame=obj)
                assert answer.success, f"{obj} from {trajectory} at {frame}: {answer.message}"
                drawn = frame_pose(scene, obj)
                world = from_xyz_rpy(drawn.xyz, drawn.rpy) @ located(answer)
                mm, deg = errors(world, perception.truth(obj))
                print(
                    f"seed {seed}: {obj} from {trajectory} at {frame}{' (located)' if at_located else ''}: "
                    f"{mm:.2f} mm, {deg:.3f} deg from the truth; {answer.distance:.2f} m, markers {answer.markers}, "
                    f"{answer.residual_px:.2f} px; {answer.offset_mm:.1f} mm, {answer.offset_deg:.1f} deg "
                    "from the drawings"
                )
                if mm > 5.0 or deg > 1.0:
                    failures.append(f"{obj}: {mm:.2f} mm, {deg:.3f} deg")
                found[obj] = _pose(answer)

            for look in LOOKS_BEFORE_THE_PULL:
                look_and_locate(*look)
            assert at.unlock_filter().success
            for trajectory, frame in (("grasp_and_pull", DIRTY), ("insert_and_release", "rack/slot_3")):
                register_and_move(trajectory, frame, found[frame])
            at.wait_for(lambda: at.held_object == "", MOTION_S, "the gripper empty")
            # the simulator puts a seated filter's frame on its slot: anywhere else, it is not in it
            rests, slot = perception.truth(DIRTY), perception.truth("rack/slot_3")
            off_mm = 1000 * float(np.linalg.norm(rests[:3, 3] - slot[:3, 3]))
            assert off_mm < 1.0, f"the dirty filter rests {off_mm:.1f} mm from rack slot 3 as it is: not in it"
            for look in LOOKS_AFTER_THE_PLACING:
                look_and_locate(*look)
            assert not failures, failures
        finally:
            perception.close()
            at.close()
