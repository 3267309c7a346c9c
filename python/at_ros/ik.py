"""Inverse kinematics per waypoint: pybullet's damped least squares from several seeds.

pybullet's solver ignores joint limits unless it switches to its null-space mode, which
converges worse; so each solution is solved unconstrained, wrapped by multiples of 2*pi into
the limits nearest to the seed, then checked for accuracy (forward kinematics), limits and
collisions. Among valid solutions the one nearest to the previous joint state wins, so
consecutive waypoints do not flip the arm's configuration.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p

from at_ros.planning_scene import PlanningScene
from at_ros.transforms import angle_between, to_xyz_quat

__all__ = ["IkSolver", "IkFailure", "rotation_vector"]

NEWTON_ITERATIONS = 8
NEWTON_DAMPING = 1e-6


def rotation_vector(r: np.ndarray) -> np.ndarray:
    """Axis times angle of a rotation matrix (the orientation error Newton steps reduce)."""
    angle = np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0))
    if angle < 1e-9:
        return np.zeros(3)
    axis = np.array([r[2, 1] - r[1, 2], r[0, 2] - r[2, 0], r[1, 0] - r[0, 1]])
    if np.pi - angle < 1e-6:  # 180 deg: the formula above vanishes; use the symmetric part
        axis = np.sqrt(np.maximum(np.diag(r) + 1.0, 0.0) / 2.0) * 2.0
    norm = np.linalg.norm(axis)
    return axis / norm * angle if norm > 0 else np.zeros(3)


@dataclass(frozen=True)
class IkFailure:
    """Why no solution was accepted: the best pose error seen and the last collision."""

    position_error: float
    orientation_error: float
    collision: str | None

    def describe(self) -> str:
        if self.collision and self.position_error < 1e-3:
            return f"every IK solution collides ({self.collision})"
        return f"unreachable (best IK error {self.position_error * 1000:.1f} mm, {np.degrees(self.orientation_error):.1f} deg)"


class IkSolver:
    def __init__(
        self,
        scene: PlanningScene,
        *,
        seeds: int = 12,
        iterations: int = 200,
        residual: float = 1e-5,
        rng: np.random.Generator | None = None,
    ) -> None:
        self.scene = scene
        self.seeds = seeds
        self.iterations = iterations
        self.residual = residual
        self.rng = rng or np.random.default_rng(1)

    def solve(
        self,
        target: np.ndarray,
        near: np.ndarray,
        *,
        position_tolerance: float = 1e-3,
        orientation_tolerance: float = 1e-2,
        check_collisions: bool = True,
        enough: int = 3,
    ) -> np.ndarray | IkFailure:
        """A joint vector putting the tool link at ``target`` (world 4x4), nearest to ``near``.

        Tries ``near`` first, then random seeds; stops after ``enough`` valid solutions.
        """
        scene = self.scene
        limits = scene.limits
        found: list[np.ndarray] = []
        best_pos, best_rot, last_collision = np.inf, np.inf, None
        seeds = [np.asarray(near, dtype=float)]
        for attempt in range(self.seeds):
            seed = seeds[0] if attempt == 0 else self.rng.uniform(limits.lower, limits.upper)
            q = self._solve_from(target, seed, near)
            if q is None:
                continue
            pose = scene.forward(q)
            pos_err = float(np.linalg.norm(pose[:3, 3] - target[:3, 3]))
            rot_err = angle_between(pose, target)
            if pos_err > position_tolerance or rot_err > orientation_tolerance:
                best_pos, best_rot = min(best_pos, pos_err), min(best_rot, rot_err)
                continue
            best_pos, best_rot = min(best_pos, pos_err), min(best_rot, rot_err)
            if check_collisions:
                why = scene.collision(q)
                if why is not None:
                    last_collision = why
                    continue
            found.append(q)
            # A solution reached from the previous state is the natural continuation: take it.
            if attempt == 0 or len(found) >= enough:
                break
        if not found:
            return IkFailure(best_pos, best_rot, last_collision)
        return min(found, key=lambda s: float(np.linalg.norm(s - near)))

    def track(self, target: np.ndarray, previous: np.ndarray, position_tolerance: float, orientation_tolerance: float) -> np.ndarray | None:
        """A solution for ``target`` continuous with ``previous`` (no restarts), within limits, or None.

        Collisions are the caller's to check: a Cartesian line wants to know where it is blocked.
        """
        q = self._newton(target, previous, position_tolerance)
        if q is None:
            return None
        q = self.wrap_into_limits(q, previous)
        if q is None:
            return None
        pose = self.scene.forward(q)
        if np.linalg.norm(pose[:3, 3] - target[:3, 3]) > position_tolerance or angle_between(pose, target) > orientation_tolerance:
            return None
        return q

    def _newton(self, target: np.ndarray, seed: np.ndarray, tolerance: float) -> np.ndarray | None:
        """Gauss-Newton on the full 6-D pose error with the tool Jacobian.

        From a nearby seed (consecutive Cartesian samples, a waypoint next to the last one) this
        converges in 2-4 iterations, ten times cheaper than pybullet's damped solver needs.
        """
        scene = self.scene
        q = np.array(seed, dtype=float)
        movable = scene.movable_positions()
        for _ in range(NEWTON_ITERATIONS):
            pose = scene.forward(q)
            dp = target[:3, 3] - pose[:3, 3]
            dr = rotation_vector(target[:3, :3] @ pose[:3, :3].T)
            if np.linalg.norm(dp) < tolerance * 0.1 and np.linalg.norm(dr) < 1e-4:
                return q
            for slot, value in zip(scene.ik_slots, q):
                movable[slot] = float(value)
            linear, angular = p.calculateJacobian(
                scene.robot, scene.tool_index, [0.0, 0.0, 0.0], movable, [0.0] * len(movable), [0.0] * len(movable),
                physicsClientId=scene.client,
            )
            jac = np.vstack([np.array(linear)[:, scene.ik_slots], np.array(angular)[:, scene.ik_slots]])
            # Damped least squares: well-defined near singularities, and a 6x6 solve is cheap.
            step = jac.T @ np.linalg.solve(jac @ jac.T + NEWTON_DAMPING * np.eye(6), np.concatenate([dp, dr]))
            if np.max(np.abs(step)) > 0.5:  # far from the seed's basin: leave it to the global solver
                return None
            q = q + step
        return None

    def _solve_from(self, target: np.ndarray, seed: np.ndarray, near: np.ndarray) -> np.ndarray | None:
        scene = self.scene
        local = self._newton(target, seed, 1e-3)
        if local is not None:
            return self.wrap_into_limits(local, near)
        scene.set_joints(seed)
        pos, quat = to_xyz_quat(target)
        raw = p.calculateInverseKinematics(
            scene.robot, scene.tool_index, pos.tolist(), quat.tolist(),
            maxNumIterations=self.iterations, residualThreshold=self.residual,
            physicsClientId=scene.client,
        )
        q = np.array([raw[i] for i in scene.ik_slots])
        # pybullet's damped solver stalls millimetres short; Newton finishes from there.
        polished = self._newton(target, q, 1e-3)
        return self.wrap_into_limits(q if polished is None else polished, near)

    def wrap_into_limits(self, q: np.ndarray, near: np.ndarray) -> np.ndarray | None:
        """Add multiples of 2*pi per joint to land inside the limits, nearest to ``near``."""
        lo, hi = self.scene.limits.lower, self.scene.limits.upper
        out = np.empty_like(q)
        for i, (value, ref) in enumerate(zip(q, near)):
            k = np.round((ref - value) / (2 * np.pi))
            candidates = [value + 2 * np.pi * (k + d) for d in (0, -1, 1, -2, 2)]
            inside = [c for c in candidates if lo[i] - 1e-9 <= c <= hi[i] + 1e-9]
            if not inside:
                return None
            out[i] = min(inside, key=lambda c: abs(c - ref))
        return out
