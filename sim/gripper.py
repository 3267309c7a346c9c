"""The two-finger gripper: moves to named poses, stops on contact, grasps what both fingers touch.

Fingers move kinematically at their velocity limit. Closing stops each finger when it touches a
filter; when both touch the same filter it is grasped (``FilterSlots.grasp``) and held while the
gripper stays closed. Opening releases it where it is.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass, field

import pybullet as p

from sim.filter_slots import FilterSlots
from sim.scene import GripperSpec
from sim.world import World

__all__ = ["Gripper", "GripperMotion"]

LOG = logging.getLogger(__name__)

#: A finger touches an object when closer than this (m).
CONTACT_DISTANCE = 0.001


@dataclass
class GripperMotion:
    """One /gripper/set request being carried out by the physics thread."""

    pose: str
    target: tuple[float, ...]
    done: threading.Event = field(default_factory=threading.Event)
    success: bool = False
    message: str = ""
    held_object: str = ""


class Gripper:
    """Finger positions and the current motion; all calls under the simulation's world lock."""

    def __init__(self, spec: GripperSpec, world: World, filters: FilterSlots, tool_link: int) -> None:
        self.spec = spec
        self._world = world
        self._filters = filters
        self._tool_link = tool_link
        self.joints = [world.joint_index[j] for j in spec.joints]
        self.fingers = [world.link_index[link] for link in spec.finger_links]
        self.speeds = [p.getJointInfo(world.robot, j, physicsClientId=world.client)[11] for j in self.joints]
        self.positions = list(spec.poses[spec.initial])
        self.velocities = [0.0] * len(self.joints)
        self.motion: GripperMotion | None = None
        self._blocked = [False] * len(self.joints)
        self._halted = False  # its last motion was stopped short by a halt

    @property
    def moving(self) -> bool:
        return self.motion is not None

    def grasp_state(self) -> str:
        """``moving``, ``holding``, ``open``, ``halted`` (stopped short of its pose by a halt, holding
        nothing), or ``empty`` (closed on nothing: a missed grasp or a slip). A halt during a close
        is not a missed grasp: a monitor for slips must not take the operator's halt for one."""
        if self.motion is not None:
            return "moving"
        if self._filters.held() is not None:
            return "holding"
        if self._halted:
            return "halted"
        opened = self.spec.poses.get("open")
        at_open = opened is not None and all(abs(q - t) < 1e-4 for q, t in zip(self.positions, opened, strict=False))
        return "open" if at_open else "empty"

    def start(self, pose: str) -> GripperMotion:
        """Begin moving to a named pose; the returned motion's ``done`` is set when it ends."""
        if pose not in self.spec.poses:
            motion = GripperMotion(pose, ())
            motion.message = f"unknown gripper pose {pose!r}; named poses are {sorted(self.spec.poses)}"
            motion.done.set()
            return motion
        if self.motion is not None:
            self.motion.message = f"superseded by a move to {pose!r}"
            self.motion.done.set()
        target = self.spec.poses[pose]
        LOG.info("gripper started: to %r", pose)  # the log says what moved when (a halt's tests read it)
        self.motion = GripperMotion(pose, target)
        self._blocked = [False] * len(self.joints)
        self._halted = False
        opening = any(t > q for t, q in zip(target, self.positions, strict=False))
        if opening and self._filters.held() is not None:
            self.motion.message = self._filters.release() + "; "
        return self.motion

    def halt(self, reason: str) -> str:
        """Stop the fingers where they are; the motion ends unsuccessful. Returns what stopped."""
        motion = self.motion
        assert motion is not None
        self._finish(False, f"halted: {reason}")
        self._halted = True
        return f"the gripper on its way to {motion.pose!r}"

    def step(self, dt: float) -> None:
        """Advance the fingers one physics step and finish the motion when they stop."""
        motion = self.motion
        if motion is None:
            return
        closing = all(t <= q for t, q in zip(motion.target, self.positions, strict=False))
        arrived = True
        for i, (joint, target) in enumerate(zip(self.joints, motion.target, strict=False)):
            if self._blocked[i]:
                self.velocities[i] = 0.0
                continue
            delta = target - self.positions[i]
            move = max(-self.speeds[i] * dt, min(self.speeds[i] * dt, delta))
            self.positions[i] += move
            self.velocities[i] = move / dt
            if abs(target - self.positions[i]) > 1e-9:
                arrived = False
            p.resetJointState(self._world.robot, joint, self.positions[i], physicsClientId=self._world.client)
            if closing and self._touched_filter(i) is not None:
                self._blocked[i] = True
        touched = [self._touched_filter(i) for i in range(len(self.joints))] if closing else []
        if closing and touched and all(t is not None and t == touched[0] for t in touched):
            filter_id = touched[0]
            assert filter_id is not None
            self._filters.grasp(filter_id, self._tool_pose())
            self._finish(True, f"closed on {filter_id}")
        elif arrived or all(self._blocked):
            self._finish(True, f"at {motion.pose}" if arrived else "stopped on contact without a grasp")

    def _finish(self, success: bool, message: str) -> None:
        motion = self.motion
        assert motion is not None
        self.velocities = [0.0] * len(self.joints)
        held = self._filters.held()
        motion.success = success
        motion.message += message
        motion.held_object = held.id if held else ""
        self.motion = None
        LOG.info("gripper %s: %s", motion.pose, motion.message)
        motion.done.set()

    def _touched_filter(self, finger: int) -> str | None:
        for state in self._filters.filters.values():
            points = p.getClosestPoints(
                self._world.robot,
                state.body,
                CONTACT_DISTANCE,
                linkIndexA=self.fingers[finger],
                physicsClientId=self._world.client,
            )
            if points:
                return state.id
        return None

    def _tool_pose(self) -> tuple[tuple[float, float, float], tuple[float, float, float, float]]:
        state = p.getLinkState(
            self._world.robot, self._tool_link, computeForwardKinematics=True, physicsClientId=self._world.client
        )
        return tuple(state[4]), tuple(state[5])  # type: ignore[return-value]
