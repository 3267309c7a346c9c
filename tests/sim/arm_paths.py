"""Joint-space waypoints for tests, from inverse kinematics on the scene's own robot model.

The tests drive the simulator the way the planner will: Cartesian tool poses turned into joint
trajectories. This is IK only (pybullet, in a client of the test's own); whether a path is
collision-free is for the simulator under test to say.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import pybullet as p

from sim.scene import Pose, filter_grasp_offset, load_scene
from sim.world import build_world

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


class ArmModel:
    def __init__(self, scene_name: str) -> None:
        self.scene = load_scene(scene_name)
        self.client = p.connect(p.DIRECT)
        self.world = build_world(self.scene, self.client, with_filters=False, with_targets=False)
        self.joints = list(self.scene.robot.arm_joints)
        self._index = [self.world.joint_index[j] for j in self.joints]
        self.limits = [p.getJointInfo(self.world.robot, j, physicsClientId=self.client)[8:12] for j in self._index]

    def close(self) -> None:
        p.disconnect(self.client)
        if self.world.marker_textures is not None:  # the scene's marker images, in a folder of their own
            self.world.marker_textures.close()

    def ik(self, link: str, pos: Sequence[float], orn: Sequence[float], seed: Sequence[float]) -> list[float]:
        """Joint positions putting ``link`` at the pose, the solution nearest ``seed``; raises if unreachable.

        pybullet's damped least squares can stall from one seed, so a few deterministic
        variations of the seed (other base rotations) are tried too.
        """
        solutions, failures = [], []
        for pan in (0.0, 0.5, -0.5, 1.0, -1.0, 1.5, -1.5):
            start = [seed[0] + pan] + list(seed[1:])
            try:
                solutions.append(self._ik_from(link, pos, orn, start))
            except AssertionError as exc:
                failures.append(str(exc))
        if not solutions:
            raise AssertionError(failures[0])
        return min(solutions, key=lambda q: sum((a - b) ** 2 for a, b in zip(q, seed, strict=False)))

    def _ik_from(self, link: str, pos: Sequence[float], orn: Sequence[float], seed: Sequence[float]) -> list[float]:
        for j, q in zip(self._index, seed, strict=False):
            p.resetJointState(self.world.robot, j, q, physicsClientId=self.client)
        target = self.world.link_index[link]
        q = list(seed)
        for _ in range(5):
            q = list(
                p.calculateInverseKinematics(
                    self.world.robot,
                    target,
                    list(pos),
                    list(orn),
                    maxNumIterations=300,
                    residualThreshold=1e-6,
                    physicsClientId=self.client,
                )
            )[: len(self._index)]
            for j, v in zip(self._index, q, strict=False):
                p.resetJointState(self.world.robot, j, v, physicsClientId=self.client)
            state = p.getLinkState(self.world.robot, target, computeForwardKinematics=True, physicsClientId=self.client)
            if math.dist(state[4], pos) < 2e-4:
                break
        error = math.dist(state[4], pos)
        diff = p.getDifferenceQuaternion(state[5], orn)
        angle = 2 * math.acos(min(1.0, abs(diff[3])))
        if error > 1e-3 or angle > 0.01:
            raise AssertionError(f"IK for {link} at {pos} failed: {error * 1000:.1f} mm, {angle:.3f} rad off")
        for (lower, upper, _, _), v, name in zip(self.limits, q, self.joints, strict=False):
            if not lower <= v <= upper:
                raise AssertionError(f"IK solution puts {name} at {v:.3f}, outside [{lower}, {upper}]")
        return q

    def grasp_pose(self, slot: str, back: float) -> tuple[Vec3, Quat]:
        """tool0 pose grasping a filter seated in ``slot``, moved ``back`` m out along the slot axis."""
        assert self.scene.filter_model is not None
        offset = filter_grasp_offset(self.scene.filter_model)
        s = self.scene.slots[slot].pose
        pos, orn = p.multiplyTransforms(s.xyz, s.quaternion, (offset.xyz[0] - back, 0, 0), offset.quaternion)
        return tuple(pos), tuple(orn)  # type: ignore[return-value]

    def slot_line(
        self, slot: str, start_back: float, end_back: float, seed: Sequence[float], step: float = 0.01
    ) -> list[list[float]]:
        """IK waypoints moving the tool straight along the slot axis from one depth to another."""
        n = max(1, int(round(abs(end_back - start_back) / step)))
        path, q = [], list(seed)
        for k in range(n + 1):
            back = start_back + (end_back - start_back) * k / n
            q = self.ik(self.scene.robot.tool_link, *self.grasp_pose(slot, back), q)
            path.append(q)
        return path

    def look_at(self, camera_link: str, target_pose: Pose, distance: float, seed: Sequence[float]) -> list[float]:
        """Put a camera link ``distance`` m out along the target's normal, looking back at it."""
        pos, orn = p.multiplyTransforms(
            target_pose.xyz, target_pose.quaternion, (0, 0, distance), p.getQuaternionFromEuler((math.pi, 0, 0))
        )
        return self.ik(camera_link, pos, orn, seed)

    def timed(
        self,
        waypoints: Sequence[Sequence[float]],
        start: Sequence[float],
        speed_fraction: float = 0.5,
        min_dt: float = 0.05,
    ) -> list[tuple[float, list[float]]]:
        """(time, positions) points, each segment at ``speed_fraction`` of the slowest joint's limit."""
        points, t, previous = [], 0.0, list(start)
        for q in waypoints:
            dt = max(
                [min_dt]
                + [abs(a - b) / (lim[3] * speed_fraction) for a, b, lim in zip(q, previous, self.limits, strict=False)]
            )
            t += dt
            points.append((t, list(q)))
            previous = list(q)
        return points
