"""The planner's own world: the robot and the obstacles in a private pybullet client.

The planner never touches the simulation's physics; it mirrors it. Obstacles come from the
scene file, their poses are kept in sync with the simulation's ground-truth frames, and an
object in the gripper is attached to the tool link so collision checks include it.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as p

from at_ros.transforms import from_xyz_quat, invert, to_xyz_quat

__all__ = ["PlanningScene", "JointLimits", "Attachment", "SceneState"]


#: Contacts shallower than this (m) are numerical touching, not collision. Half of what the
#: simulation tolerates (1 mm), so a plan that passes here is not refused on execution.
PENETRATION_ALLOWANCE = 0.0005


@dataclass(frozen=True)
class JointLimits:
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray


@dataclass
class Attachment:
    """An object rigidly carried by the tool link."""

    name: str
    body: int
    tool_T_object: np.ndarray  # noqa: N815 (a_T_b: the transform notation of robotics)


@dataclass(frozen=True)
class SceneState:
    """A moment of the planning scene to go back to (see :meth:`PlanningScene.snapshot`)."""

    attachment: Attachment | None
    object_poses: dict[str, np.ndarray]


class PlanningScene:
    """Robot + obstacles in a DIRECT pybullet client, with fast validity checks.

    Args:
        urdf: robot model.
        joint_names: the planned joints, in the order of every joint vector here.
        tool_link: the link whose pose waypoints command.
        base_pose: world pose of the robot base (4x4).
        client: a pybullet client already holding the obstacles; a new DIRECT one by default.
        gripper_links: links allowed to touch graspable objects (the fingers closing on a part).
    """

    def __init__(
        self,
        urdf: Path | str,
        joint_names: list[str] | tuple[str, ...],
        tool_link: str,
        *,
        client: int | None = None,
        base_pose: np.ndarray | None = None,
        gripper_links: tuple[str, ...] = (),
    ) -> None:
        self.client = p.connect(p.DIRECT) if client is None else client
        base = np.eye(4) if base_pose is None else base_pose
        pos, quat = to_xyz_quat(base)
        self.robot = p.loadURDF(
            str(urdf),
            pos.tolist(),
            quat.tolist(),
            useFixedBase=True,
            flags=p.URDF_USE_SELF_COLLISION,
            physicsClientId=self.client,
        )
        self.joint_names = tuple(joint_names)
        self.dof = len(self.joint_names)
        #: The URDF's root link: the robot's base frame, in which messages give poses.
        self.base_link: str = p.getBodyInfo(self.robot, physicsClientId=self.client)[0].decode()
        self._link_index: dict[str, int] = {self.base_link: -1}
        joint_index: dict[str, int] = {}
        self._movable: list[int] = []
        self._parent: dict[int, int] = {}
        lower, upper, velocity = {}, {}, {}
        for j in range(p.getNumJoints(self.robot, physicsClientId=self.client)):
            info = p.getJointInfo(self.robot, j, physicsClientId=self.client)
            name, jtype, link = info[1].decode(), info[2], info[12].decode()
            self._link_index[link] = j
            self._parent[j] = info[16]
            joint_index[name] = j
            if jtype != p.JOINT_FIXED:
                self._movable.append(j)
            lower[name], upper[name], velocity[name] = info[8], info[9], info[11]
        missing = [n for n in self.joint_names if n not in joint_index]
        if missing:
            raise ValueError(f"{urdf}: joints {missing} not in the model; it has {sorted(joint_index)}")
        if tool_link not in self._link_index:
            raise ValueError(f"{urdf}: tool link {tool_link!r} not in the model; links: {sorted(self._link_index)}")
        self.joint_indices = [joint_index[n] for n in self.joint_names]
        self.tool_index = self._link_index[tool_link]
        # Position of each planned joint inside pybullet's IK result (one entry per movable joint).
        self.ik_slots = [self._movable.index(j) for j in self.joint_indices]
        lo = np.array([lower[n] for n in self.joint_names])
        hi = np.array([upper[n] for n in self.joint_names])
        unlimited = hi <= lo  # continuous joints report upper < lower
        lo[unlimited], hi[unlimited] = -2 * np.pi, 2 * np.pi
        vel = np.array([velocity[n] if velocity[n] > 0 else 1.0 for n in self.joint_names])
        self.limits = JointLimits(lo, hi, vel)
        self.gripper_link_indices = {self._link_index[n] for n in gripper_links if n in self._link_index}
        self.obstacles: dict[str, int] = {}
        self.graspable: set[str] = set()
        self.frames_fixed: dict[str, tuple[str, ...]] = {}  # obstacle -> named frames fixed to it
        self.attachment: Attachment | None = None
        self._allowed_self_pairs = self._adjacent_pairs()
        self.set_joints(np.clip(np.zeros(self.dof), lo, hi))
        # Pairs touching at the zero pose are allowed forever (MoveIt's "default" collisions).
        self._allowed_self_pairs |= {frozenset((c[3], c[4])) for c in self._self_contacts()}

    # --- world -----------------------------------------------------------------------------

    def close(self) -> None:
        p.disconnect(self.client)

    def set_base_pose(self, pose: np.ndarray) -> None:
        """Place the robot's root link frame (URDF) at ``pose``; pybullet places its inertial frame."""
        local_pos, local_quat = p.getDynamicsInfo(self.robot, -1, physicsClientId=self.client)[3:5]
        pos, quat = to_xyz_quat(pose @ from_xyz_quat(local_pos, local_quat))
        p.resetBasePositionAndOrientation(self.robot, pos.tolist(), quat.tolist(), physicsClientId=self.client)

    def base_pose(self) -> np.ndarray:
        """World pose of the robot's root link frame (pybullet keeps its inertial frame's)."""
        pos, quat = p.getBasePositionAndOrientation(self.robot, physicsClientId=self.client)
        local_pos, local_quat = p.getDynamicsInfo(self.robot, -1, physicsClientId=self.client)[3:5]
        pose: np.ndarray = from_xyz_quat(pos, quat) @ invert(from_xyz_quat(local_pos, local_quat))
        return pose

    def add_obstacle(self, name: str, body: int, *, graspable: bool = False, frames: Sequence[str] = ()) -> None:
        """Register a body created in this client (by the scene loader) under its frame name,
        with the named frames fixed to it (a registration to one of them moves it)."""
        self.obstacles[name] = body
        self.frames_fixed[name] = tuple(frames)
        if graspable:
            self.graspable.add(name)

    def add_box(self, name: str, size: tuple[float, float, float], pose: np.ndarray, *, graspable: bool = False) -> int:
        shape = p.createCollisionShape(p.GEOM_BOX, halfExtents=[s / 2 for s in size], physicsClientId=self.client)
        pos, quat = to_xyz_quat(pose)
        body = p.createMultiBody(0, shape, -1, pos.tolist(), quat.tolist(), physicsClientId=self.client)
        self.add_obstacle(name, body, graspable=graspable)
        return int(body)

    def set_obstacle_pose(self, name: str, pose: np.ndarray) -> None:
        pos, quat = to_xyz_quat(pose)
        p.resetBasePositionAndOrientation(
            self.obstacles[name], pos.tolist(), quat.tolist(), physicsClientId=self.client
        )

    def obstacle_pose(self, name: str) -> np.ndarray:
        pos, quat = p.getBasePositionAndOrientation(self.obstacles[name], physicsClientId=self.client)
        return from_xyz_quat(pos, quat)

    def object_name(self, name: str) -> str | None:
        """The obstacle a simulation object name refers to: ``CDRA-F-0007`` is ``filter/CDRA-F-0007``."""
        if name in self.obstacles:
            return name
        return next((n for n in self.obstacles if n.rsplit("/", 1)[-1] == name), None)

    def attach(self, name: str, tool_T_object: np.ndarray | None = None) -> None:  # noqa: N803 (a_T_b: the transform notation of robotics)
        """Carry obstacle ``name`` with the tool; by default where it is now relative to the tool."""
        if name not in self.obstacles:
            raise KeyError(f"unknown object {name!r}")
        if tool_T_object is None:
            tool_T_object = invert(self.tool_pose()) @ self.obstacle_pose(name)  # noqa: N806 (a_T_b: the transform notation of robotics)
        self.attachment = Attachment(name, self.obstacles[name], tool_T_object)

    def detach(self) -> None:
        self.attachment = None

    def snapshot(self) -> SceneState:
        """What planning changes in the world: the attachment and where the graspable objects are."""
        return SceneState(self.attachment, {name: self.obstacle_pose(name) for name in self.graspable})

    def restore(self, state: SceneState) -> None:
        self.attachment = state.attachment
        for name, pose in state.object_poses.items():
            self.set_obstacle_pose(name, pose)

    def nearest_graspable(self, point: np.ndarray, *, within: float) -> str | None:
        """The graspable object whose origin is closest to ``point`` (e.g. the fingers' centre)."""
        best, best_d = None, within
        for name in self.graspable:
            d = float(np.linalg.norm(self.obstacle_pose(name)[:3, 3] - point))
            if d <= best_d:
                best, best_d = name, d
        return best

    # --- robot -----------------------------------------------------------------------------

    def set_joints(self, q: np.ndarray | list[float]) -> None:
        p.resetJointStatesMultiDof(self.robot, self.joint_indices, [[float(v)] for v in q], physicsClientId=self.client)
        if self.attachment is not None:
            pose = self.tool_pose() @ self.attachment.tool_T_object
            pos, quat = to_xyz_quat(pose)
            p.resetBasePositionAndOrientation(
                self.attachment.body, pos.tolist(), quat.tolist(), physicsClientId=self.client
            )

    def movable_positions(self) -> list[float]:
        """Positions of every movable joint (arm and gripper), in pybullet's order."""
        states = p.getJointStates(self.robot, self._movable, physicsClientId=self.client)
        return [s[0] for s in states]

    def tool_pose(self) -> np.ndarray:
        state = p.getLinkState(self.robot, self.tool_index, computeForwardKinematics=True, physicsClientId=self.client)
        return from_xyz_quat(state[4], state[5])

    def forward(self, q: np.ndarray | list[float]) -> np.ndarray:
        self.set_joints(q)
        return self.tool_pose()

    def within_limits(self, q: np.ndarray) -> bool:
        return bool(np.all(q >= self.limits.lower - 1e-9) and np.all(q <= self.limits.upper + 1e-9))

    # --- collisions ------------------------------------------------------------------------

    def collision(self, q: np.ndarray | list[float]) -> str | None:
        """Why ``q`` is in collision ("link_a with obstacle"), or None when it is free.

        "with", not a separator: object names hold slashes (``filter/CDRA-F-0007``)."""
        self.set_joints(q)
        p.performCollisionDetection(physicsClientId=self.client)
        names = self._body_names()
        held = self.attachment.body if self.attachment else None
        for c in p.getContactPoints(bodyA=self.robot, physicsClientId=self.client):
            if c[8] > -PENETRATION_ALLOWANCE:
                continue
            other, link_a, link_b = c[2], c[3], c[4]
            if other == self.robot:
                if frozenset((link_a, link_b)) in self._allowed_self_pairs:
                    continue
                return f"{self._link_name(link_a)} with {self._link_name(link_b)}"
            if other == held:
                continue  # the carried part sits in the gripper
            if link_a in self.gripper_link_indices and names.get(other) in self.graspable:
                continue
            return f"{self._link_name(link_a)} with {names.get(other, other)}"
        if held is not None:
            for c in p.getContactPoints(bodyA=held, physicsClientId=self.client):
                other = c[2]
                if other == self.robot or c[8] > -PENETRATION_ALLOWANCE:
                    continue
                return f"{self.attachment.name} with {names.get(other, other)}"  # type: ignore[union-attr]
        return None

    def is_valid(self, q: np.ndarray | list[float]) -> bool:
        return self.collision(q) is None

    def _self_contacts(self) -> list[tuple[Any, ...]]:
        p.performCollisionDetection(physicsClientId=self.client)
        return [c for c in p.getContactPoints(bodyA=self.robot, bodyB=self.robot, physicsClientId=self.client)]

    def _adjacent_pairs(self) -> set[frozenset[int]]:
        pairs = {frozenset((j, parent)) for j, parent in self._parent.items()}
        # Links joined by fixed joints move as one piece: allow all pairs inside such a piece.
        fixed = {j for j in self._parent if j not in self._movable}
        for a, b in itertools.combinations(list(self._parent) + [-1], 2):
            if self._rigidly_joined(a, b, fixed):
                pairs.add(frozenset((a, b)))
        return pairs

    def _rigidly_joined(self, a: int, b: int, fixed: set[int]) -> bool:
        def root(link: int) -> int:
            while link in fixed:
                link = self._parent[link]
            return link

        return root(a) == root(b)

    def _link_name(self, index: int) -> str:
        return next((n for n, i in self._link_index.items() if i == index), str(index))

    def _body_names(self) -> dict[int, str]:
        return {body: name for name, body in self.obstacles.items()}
