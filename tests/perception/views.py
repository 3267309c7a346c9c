"""Test cameras looking at each marked object of the IVA scene, written into a copy of the scene.

The cameras are fixed cameras added to a copy of the shipped scene, aimed where the *scene file*
puts each object (as a robot that has not located it yet would aim): so on a displaced world the
object is near the middle of the image, never exactly there.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pybullet as p
import yaml

from at_ros.transforms import angle_between, from_xyz_quat, from_xyz_rpy, quat_from_matrix
from sim.displacement import compose, displaced_scene
from sim.scene import SCENES_DIR, Scene, load_scene, marker_frame_pose
from sim.world import build_world

#: The seed of the displaced world every test here runs on.
DISPLACE_SEED = 11


@dataclass(frozen=True)
class View:
    """A test camera: which object it looks at, from how far (m) and from which side (deg)."""

    camera: str
    obj: str
    distance: float
    azimuth_deg: float
    elevation_deg: float


def aim(scene: Scene, obj: str) -> tuple[np.ndarray, np.ndarray]:
    """The middle of an object's markers and their outward normal, in world (nominal)."""
    frame = marker_frame_pose(scene, obj)
    poses = [compose(frame, m.pose) for m in scene.markers if m.frame == obj]
    centre = np.mean([p.xyz for p in poses], axis=0)
    normal = from_xyz_quat(poses[0].xyz, poses[0].quaternion)[:3, 2]
    return centre, normal


def camera_entry(scene: Scene, view: View) -> dict[str, object]:
    """A fixed camera ``view.distance`` from the object, turned ``azimuth`` about the vertical
    from its markers' normal and raised ``elevation`` above it, looking at the markers' middle.

    Aimed where ``scene`` has the object: the nominal scene for what a robot looks for first,
    the displaced one for a filter, which a robot looks at square-on once it has located its
    slot (the handle beside the filter's small markers hides one from more than ~10 deg off)."""
    centre, normal = aim(scene, view.obj)
    az, el = math.radians(view.azimuth_deg), math.radians(view.elevation_deg)
    horizontal = np.array([normal[0], normal[1], 0.0])
    horizontal /= np.linalg.norm(horizontal)
    turned = np.array(
        [
            horizontal[0] * math.cos(az) - horizontal[1] * math.sin(az),
            horizontal[0] * math.sin(az) + horizontal[1] * math.cos(az),
            0.0,
        ]
    )
    direction = turned * math.cos(el) + np.array([0.0, 0.0, math.sin(el)])
    eye = centre + view.distance * direction
    return {
        "name": view.camera,
        "eye": [round(float(v), 4) for v in eye],
        "target": [round(float(v), 4) for v in centre],
        "fov_deg": 45,
        "width": 640,
        "height": 480,
        "near": 0.02,
    }


def views() -> list[View]:
    """Every marked object of the IVA scene seen from 0.6 and 1.0 m (the filters, whose markers
    are 3.6 cm beside a handle, from 0.3 m), from left and right of straight on, from above the table,
    as a wrist camera looks at what the arm is about to reach for."""
    scene = load_scene("iva")
    found = []
    for obj in dict.fromkeys(m.frame for m in scene.markers):
        small = obj.startswith("filter/")
        for distance in (0.3,) if small else (0.6, 1.0):
            for azimuth in (-5.0, 5.0) if small else (-15.0, 15.0):
                side = "left" if azimuth < 0 else "right"
                name = f"{obj.replace('/', '_').replace('-', '_')}_{int(distance * 100)}cm_{side}"
                found.append(View(name, obj, distance, azimuth, 10.0 if small else 25.0))
    return found


#: Where the UR10 starts in the wrist camera's test scene: its camera on the cabinet's markers.
WRIST_VIEW = View("wrist_camera", "cabinet/slot", 0.6, 10.0, 20.0)


def view_pose(scene: Scene, view: View) -> tuple[np.ndarray, np.ndarray]:
    """Where a camera of ``view`` is, and its optical frame's quaternion (x right, y down).

    An elevation of 90 deg looks straight down the markers' normal (x along the markers' x);
    any other is :func:`camera_entry`'s, upright."""
    if view.elevation_deg == 90.0:
        centre, _ = aim(scene, view.obj)
        marker = next(compose(marker_frame_pose(scene, view.obj), m.pose) for m in scene.markers if m.frame == view.obj)
        facing = from_xyz_quat(centre, marker.quaternion) @ from_xyz_rpy((0.0, 0.0, view.distance), (math.pi, 0.0, 0.0))
        return facing[:3, 3], quat_from_matrix(facing[:3, :3])
    entry = camera_entry(scene, view)
    eye, target = np.array(entry["eye"]), np.array(entry["target"])
    z = (target - eye) / np.linalg.norm(target - eye)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    return eye, quat_from_matrix(np.column_stack([x, np.cross(z, x), z]))


def arm_looking(scene: Scene, view: View) -> list[float]:
    """Joint positions of the scene's arm that put ``view.camera`` (a camera link) at
    :func:`view_pose` (pybullet IK on the scene's robot, checked by forward kinematics)."""
    eye, orientation = view_pose(scene, view)
    client = p.connect(p.DIRECT)
    world = build_world(scene, client, with_filters=False, with_targets=False)
    try:
        joints = [world.joint_index[j] for j in scene.robot.arm_joints]
        for j, q in zip(joints, scene.robot.initial_positions, strict=True):
            p.resetJointState(world.robot, j, q, physicsClientId=client)
        link = world.link_index[view.camera]
        for _ in range(10):
            solution = p.calculateInverseKinematics(
                world.robot, link, eye.tolist(), orientation.tolist(), maxNumIterations=300,
                residualThreshold=1e-7, physicsClientId=client,
            )[: len(joints)]  # fmt: skip
            for j, q in zip(joints, solution, strict=True):
                p.resetJointState(world.robot, j, q, physicsClientId=client)
        position, reached = p.getLinkState(world.robot, link, computeForwardKinematics=True, physicsClientId=client)[
            4:6
        ]
    finally:
        p.disconnect(client)
        if world.marker_textures is not None:
            world.marker_textures.close()
    off = angle_between(from_xyz_quat(eye, orientation), from_xyz_quat(position, reached))
    assert np.linalg.norm(np.array(position) - eye) < 1e-3 and off < 0.01, f"IK for {view.camera} missed"
    return [round(float(q), 6) for q in solution]


def write_scene(folder: Path, extra: list[View], arm: View | None = None, name: str = "iva") -> Path:
    """Shipped scene ``name`` with the ``extra`` cameras, and the arm starting with its camera
    where ``arm`` says (else where the scene starts it), written into ``folder``."""
    scene = load_scene(name)
    displaced = displaced_scene(scene, DISPLACE_SEED)
    data = yaml.safe_load((SCENES_DIR / f"{name}.yaml").read_text())
    data["robot"]["urdf"] = str((SCENES_DIR / data["robot"]["urdf"]).resolve())
    data["cameras"] += [camera_entry(displaced if v.obj.startswith("filter/") else scene, v) for v in extra]
    if arm is not None:
        data["robot"]["initial_positions"] = arm_looking(scene, arm)
    path = folder / f"{name}_views.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path
