"""The 3D view's test data, made from the shipped files by the real producers.

Scenes and URDFs from ``sim/``, frames from a real ``sim.simulation.Simulation`` (pybullet),
template statuses from the AT server's own code (``at_ros.instance`` and
``at_ros.template_messages``, converted to rosbridge JSON by the bridge's converter), all turned
into the contract by ``console.spatial_scene``. Forward kinematics for the expected poses
comes from a separate pybullet client that loads the URDF itself.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as p
import yaml

from at_ros.instance import Registration, TemplateInstance
from at_ros.library import load_library
from at_ros.robot_config import RobotConfig, load_robot_configs
from at_ros.template_messages import instance_status, template_config
from at_ros.transforms import from_xyz_quat, invert, to_xyz_quat
from bridge.rosbridge.conversion import message_to_dict
from console.spatial_scene import scene_document
from console.spatial_updates import PlanSegment, plan_update, templates_update
from sim.scene import load_scene
from sim.simulation import Simulation

REPO = Path(__file__).resolve().parents[2]
SCENES = REPO / "sim" / "scenes"


def matrix(pose: Mapping[str, Any]) -> np.ndarray:
    """4x4 of a contract pose."""
    return from_xyz_quat(pose["xyz"], pose["quat"])


@dataclass
class Habitat:
    """One shipped scene: its file's data, a simulation of it and a kinematics client."""

    name: str
    mapping: dict[str, Any]
    urdf_path: Path
    sim: Simulation
    fk_client: int
    fk_robot: int
    fk_joints: dict[str, int]
    fk_links: dict[str, int]

    @classmethod
    def open(cls, name: str) -> Habitat:
        path = SCENES / f"{name}.yaml"
        mapping = yaml.safe_load(path.read_text())
        scene = load_scene(path)
        sim = Simulation(scene)
        client = p.connect(p.DIRECT)
        base = scene.robot.base
        robot = p.loadURDF(
            str(scene.robot.urdf), list(base.xyz), list(base.quaternion), useFixedBase=True, physicsClientId=client
        )
        joints, links = {}, {}
        for j in range(p.getNumJoints(robot, physicsClientId=client)):
            info = p.getJointInfo(robot, j, physicsClientId=client)
            joints[info[1].decode()] = j
            links[info[12].decode()] = j
        return cls(name, mapping, scene.robot.urdf, sim, client, robot, joints, links)

    def close(self) -> None:
        p.disconnect(self.fk_client)
        p.disconnect(self.sim.client)

    @property
    def arm_joints(self) -> list[str]:
        return list(self.mapping["robot"]["arm_joints"])

    def frames_json(self) -> dict[str, Any]:
        """/sim/frames as rosbridge JSON (caretaker_sim_msgs/NamedPoses)."""
        names, poses = [], []
        for name, (xyz, quat) in self.sim.frames():
            names.append(name)
            poses.append(
                {
                    "position": dict(zip("xyz", map(float, xyz), strict=True)),
                    "orientation": dict(zip("xyzw", map(float, quat), strict=True)),
                }
            )
        return {"header": {"frame_id": "world", "stamp": {"sec": 1, "nanosec": 0}}, "names": names, "poses": poses}

    def frame(self, name: str) -> np.ndarray:
        for n, (xyz, quat) in self.sim.frames():
            if n == name:
                return from_xyz_quat(xyz, quat)
        raise KeyError(name)

    def document(self) -> dict[str, Any]:
        return scene_document(self.mapping, self.urdf_path.read_text(), frames=self.frames_json())

    def link_poses(self, positions: Mapping[str, float]) -> dict[str, np.ndarray]:
        """World pose of every URDF link for ``positions`` (others at zero), from pybullet."""
        for name, j in self.fk_joints.items():
            p.resetJointState(self.fk_robot, j, float(positions.get(name, 0.0)), physicsClientId=self.fk_client)
        out = {}
        # pybullet reports the base's centre of mass; its link frame sits the inertial offset back.
        pos, orn = p.getBasePositionAndOrientation(self.fk_robot, physicsClientId=self.fk_client)
        inertial = p.getDynamicsInfo(self.fk_robot, -1, physicsClientId=self.fk_client)
        base = from_xyz_quat(pos, orn) @ invert(from_xyz_quat(inertial[3], inertial[4]))
        out[p.getBodyInfo(self.fk_robot, physicsClientId=self.fk_client)[0].decode()] = base
        for name, j in self.fk_links.items():
            state = p.getLinkState(self.fk_robot, j, computeForwardKinematics=True, physicsClientId=self.fk_client)
            out[name] = from_xyz_quat(state[4], state[5])
        return out

    def ik(self, tool_link: str, goal: np.ndarray, seed: Sequence[float]) -> list[float]:
        """Arm joints that bring ``tool_link`` near ``goal`` (pybullet's solver; the plan only needs to be a path)."""
        for name, q in zip(self.arm_joints, seed, strict=True):
            p.resetJointState(self.fk_robot, self.fk_joints[name], q, physicsClientId=self.fk_client)
        xyz, quat = to_xyz_quat(goal)
        solution = p.calculateInverseKinematics(
            self.fk_robot,
            self.fk_links[tool_link],
            list(xyz),
            list(quat),
            maxNumIterations=200,
            residualThreshold=1e-5,
            physicsClientId=self.fk_client,
        )
        movable = [
            name
            for name, j in sorted(self.fk_joints.items(), key=lambda kv: kv[1])
            if p.getJointInfo(self.fk_robot, j, physicsClientId=self.fk_client)[2] != p.JOINT_FIXED
        ]
        by_name = dict(zip(movable, solution, strict=True))
        return [float(by_name[n]) for n in self.arm_joints]


@dataclass
class RunningTemplate:
    """An AT instance as the AT server holds it, registered to a named frame."""

    instance: TemplateInstance
    robot: RobotConfig
    habitat: Habitat

    @classmethod
    def add(cls, habitat: Habitat, template: str, robot: str, *, object_name: str, frame: str) -> RunningTemplate:
        config = load_robot_configs()[robot]
        root = habitat.frame(config.frame_id) @ config.root_offset_matrix
        instance = TemplateInstance(
            load_library(REPO / "python" / "at_ros" / "library" / "templates")[template], 0, config, root
        )
        running = cls(instance, config, habitat)
        running.register(object_name, frame, np.eye(4))
        return running

    def register(self, object_name: str, frame: str, offset: np.ndarray) -> None:
        self.registered_to = frame
        self.instance.register(object_name, Registration(frame, offset, self.habitat.frame(frame)))

    def status_json(self, trajectory: str) -> dict[str, Any]:
        status = instance_status(
            self.instance, trajectory, "world", np.eye(4), plan_status="IDLE", execute_status="IDLE", plan_valid=False
        )
        data = message_to_dict(status)
        for info in data["object_info"]:  # the proposed ObjectInfo.registered_to
            info["registered_to"] = self.registered_to
        return data

    def update(self, trajectory: str) -> dict[str, Any]:
        config = message_to_dict(template_config(self.instance.template, self.robot))
        return templates_update(
            [self.status_json(trajectory)],
            frames=self.habitat.frames_json(),
            configs={self.instance.template.name: config},
        )

    def resolved(self, trajectory: str) -> list[Any]:
        t = self.instance.trajectory(trajectory)
        return self.instance.resolve(t, self.instance.end_effector(t, []))

    def plan(
        self, trajectory: str, start: Sequence[float], *, steps_per_segment: int = 12, seconds_per_step: float = 0.1
    ) -> dict[str, Any]:
        """A plan update through every waypoint: IK goals joined by straight joint lines."""
        segments = []
        previous = list(start)
        previous_goal: np.ndarray | None = None
        for wp in self.resolved(trajectory):
            # A waypoint at the pose of the one before (closing the gripper) moves no joint.
            same = previous_goal is not None and np.allclose(previous_goal, wp.tool_goal)
            goal = previous if same else self.habitat.ik(self.robot.tool_link, wp.tool_goal, previous)
            previous_goal = wp.tool_goal
            points = []
            if not same:
                for k in range(1, steps_per_segment + 1):
                    f = k / steps_per_segment
                    t = k * seconds_per_step
                    points.append(
                        {
                            "positions": [a + f * (b - a) for a, b in zip(previous, goal, strict=True)],
                            "time_from_start": {"sec": int(t), "nanosec": int(round((t - int(t)) * 1e9))},
                        }
                    )
            segments.append(
                PlanSegment(wp.label, {"joint_names": self.habitat.arm_joints, "points": points}, wp.end_effector_pose)
            )
            previous = goal
        end = self.habitat.link_poses(dict(zip(self.habitat.arm_joints, previous, strict=True)))[self.robot.tool_link]
        xyz, quat = to_xyz_quat(end)
        return plan_update(
            instance=self.instance.key,
            trajectory=trajectory,
            joint_names=self.habitat.arm_joints,
            start_positions=start,
            segments=segments,
            tool_link=self.robot.tool_link,
            end_pose={
                "position": dict(zip("xyz", map(float, xyz), strict=True)),
                "orientation": dict(zip("xyzw", map(float, quat), strict=True)),
            },
        )


def relative(frame: np.ndarray, pose: np.ndarray) -> np.ndarray:
    return invert(frame) @ pose


def world_boxes(body: Mapping[str, Any]) -> list[tuple[np.ndarray, np.ndarray]]:
    """A scene file body's box shapes as world-aligned boxes (low, high corners) around their
    corners, as the 3D view bounds a mesh."""
    pose = body.get("pose", {"xyz": [0, 0, 0], "rpy": [0, 0, 0]})
    rotation = np.array(p.getMatrixFromQuaternion(p.getQuaternionFromEuler(pose["rpy"]))).reshape(3, 3)
    boxes = []
    for shape in body["shapes"]:
        half = np.array(shape["size"]) / 2
        corners = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * half
        world = (corners + np.array(shape.get("xyz", [0, 0, 0]))) @ rotation.T + np.array(pose["xyz"])
        boxes.append((world.min(axis=0), world.max(axis=0)))
    return boxes


def crosses(box: tuple[np.ndarray, np.ndarray], start: np.ndarray, end: np.ndarray) -> bool:
    """Whether the segment start..end passes through the axis-aligned box (slab test)."""
    d = end - start
    low, high = 0.0, 1.0
    for axis in range(3):
        if abs(d[axis]) < 1e-12:
            if not box[0][axis] <= start[axis] <= box[1][axis]:
                return False
            continue
        t0, t1 = sorted(((box[0][axis] - start[axis]) / d[axis], (box[1][axis] - start[axis]) / d[axis]))
        low, high = max(low, t0), min(high, t1)
    return low <= high
