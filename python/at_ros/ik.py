"""Inverse kinematics per waypoint, inside the joint limits while solving.

The solver is damped least squares (Gauss-Newton on the 6-D pose error with the tool Jacobian)
projected onto the joint limits: a joint at a limit that the step would push further out is
held there and the other joints make up the motion, so the search never leaves the robot's
range. An arm whose "natural" solution lies outside a limit therefore finds the one inside it,
instead of converging outside and being thrown away. Seeds are the previous state first (the
natural continuation), then random states within the limits; pybullet's unconstrained solver
is a fallback that finds distant basins, its answer wrapped by whole turns into the limits and
finished by the projected solver.

When no solution is accepted, the failure gives one reason, decided in this order so that it
never contradicts itself: solutions within the limits reach the pose but collide (naming the
contact), only solutions outside the limits reach it (naming the joints, the values they would
need and the limits they pass), or nothing reaches it even ignoring limits and collisions: it is
out of reach.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pybullet as p

from at_ros.planning_scene import PlanningScene
from at_ros.transforms import angle_between, to_xyz_quat

__all__ = ["IkSolver", "IkFailure", "LimitExcess", "rotation_vector"]

#: Iterations of the projected solver from a nearby seed (a Cartesian sample, the last waypoint).
NEWTON_ITERATIONS = 8
#: Iterations from a random seed: steps are capped, so distant poses take more of them.
GLOBAL_ITERATIONS = 60
NEWTON_DAMPING = 1e-6
#: Largest joint change of one step from a random seed (rad); larger steps overshoot.
GLOBAL_STEP = 0.4
#: A joint this close to a limit counts as at it (rad).
AT_LIMIT = 1e-9
#: How near the answer of pybullet's solver (which ignores the limits) must come to count as
#: reaching the pose: its residual is looser than ours, and only then do its limits matter.
UNCONSTRAINED_POSITION = 5e-3
UNCONSTRAINED_ORIENTATION = 0.05


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
class LimitExcess:
    """A joint that a solution reaching the pose puts outside its range: the value it would need
    (over whole turns, the one nearest the range) and the limit it passes."""

    joint: str
    value: float
    limit: float
    upper: bool

    @property
    def excess(self) -> float:
        return abs(self.value - self.limit)

    def __str__(self) -> str:
        side = "upper" if self.upper else "lower"
        return f"{self.joint} would be {self.value:.2f} rad, beyond its {side} limit {self.limit:.2f} rad"


@dataclass(frozen=True)
class IkFailure:
    """Why no solution was accepted: one reason, the first of these that holds.

    ``collision``: solutions within the limits reach the pose and all collide; the contact of the
    one nearest the seed state (the configuration an operator expects). ``beyond_limits``: only
    solutions outside the limits reach it; the joints of the one needing the least. Neither: no
    attempt reached it even ignoring limits and collisions, it is out of reach. How near an attempt
    came is not said: out of reach, pybullet's solver trades position for orientation, so its
    nearest answer overstates the distance.
    """

    collision: str | None = None
    beyond_limits: tuple[LimitExcess, ...] = ()

    def describe(self) -> str:
        """The reason as the rest of a sentence whose subject is the pose: "is out of reach"."""
        if self.collision is not None:
            return f"is reachable only in collision ({self.collision})"
        if self.beyond_limits:
            return f"is reachable only outside the joint limits ({', '.join(map(str, self.beyond_limits))})"
        return "is out of reach"


def _total(excess: tuple[LimitExcess, ...]) -> float:
    """How far a solution is outside the limits: of several, the one needing the least is named."""
    return sum(e.excess for e in excess)


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
        #: After a :meth:`track` that failed: the joints its last iterate held at a limit.
        self.blocked_by: str | None = None
        self._last_iterate: np.ndarray | None = None

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
        """A joint vector within the limits putting the tool link at ``target`` (world 4x4),
        nearest to ``near``.

        Tries ``near`` first, then random seeds within the limits; stops after ``enough`` valid
        solutions. Without one, the failure says why (:class:`IkFailure`).
        """
        scene = self.scene
        limits = scene.limits
        near = np.clip(np.asarray(near, dtype=float), limits.lower, limits.upper)
        found: list[np.ndarray] = []
        colliding: list[tuple[np.ndarray, str]] = []
        beyond: tuple[LimitExcess, ...] = ()
        for attempt in range(self.seeds):
            seed = near if attempt == 0 else self.rng.uniform(limits.lower, limits.upper)
            q, raw = self._solve_from(target, seed, near, position_tolerance)
            if q is None:
                excess = self._beyond_limits(raw, target, position_tolerance) if raw is not None else ()
                if excess and (not beyond or _total(excess) < _total(beyond)):
                    beyond = excess
                continue
            position, orientation = self._pose_error(q, target)
            if position > position_tolerance or orientation > orientation_tolerance:
                continue
            if check_collisions:
                why = scene.collision(q)
                if why is not None:
                    colliding.append((q, why))
                    continue
            found.append(q)
            # A solution reached from the previous state is the natural continuation: take it.
            if attempt == 0 or len(found) >= enough:
                break
        if not found:
            expected = min(colliding, key=lambda c: float(np.linalg.norm(c[0] - near)), default=None)
            return IkFailure(expected[1] if expected else None, beyond)
        return min(found, key=lambda s: float(np.linalg.norm(s - near)))

    def track(
        self, target: np.ndarray, previous: np.ndarray, position_tolerance: float, orientation_tolerance: float
    ) -> np.ndarray | None:
        """A solution for ``target`` continuous with ``previous`` (no restarts), within limits, or None.

        Collisions are the caller's to check: a Cartesian line wants to know where it is blocked.
        """
        self.blocked_by = None
        q = self._newton(target, previous, position_tolerance, iterations=NEWTON_ITERATIONS, max_step=None)
        if q is not None:
            position, orientation = self._pose_error(q, target)
            if position <= position_tolerance and orientation <= orientation_tolerance:
                return q
        if self._last_iterate is not None:
            self.blocked_by = self.limit_blocking(self._last_iterate)
        return None

    def limit_blocking(self, q: np.ndarray) -> str | None:
        """The joints of ``q`` that sit at a limit, for messages ("elbow_joint at its upper limit 2.50 rad")."""
        lo, hi = self.scene.limits.lower, self.scene.limits.upper
        at = [
            f"{name} at its {'lower' if v <= lo[i] + 1e-6 else 'upper'} limit "
            f"{lo[i] if v <= lo[i] + 1e-6 else hi[i]:.2f} rad"
            for i, (name, v) in enumerate(zip(self.scene.joint_names, q, strict=False))
            if v <= lo[i] + 1e-6 or v >= hi[i] - 1e-6
        ]
        return ", ".join(at) or None

    def _jacobian(self, q: np.ndarray, movable: list[float]) -> np.ndarray:
        scene = self.scene
        for slot, value in zip(scene.ik_slots, q, strict=False):
            movable[slot] = float(value)
        linear, angular = p.calculateJacobian(
            scene.robot,
            scene.tool_index,
            [0.0, 0.0, 0.0],
            movable,
            [0.0] * len(movable),
            [0.0] * len(movable),
            physicsClientId=scene.client,
        )
        return np.vstack([np.array(linear)[:, scene.ik_slots], np.array(angular)[:, scene.ik_slots]])

    def _newton(
        self, target: np.ndarray, seed: np.ndarray, tolerance: float, *, iterations: int, max_step: float | None
    ) -> np.ndarray | None:
        """Damped least squares projected onto the joint limits; None if it does not converge.

        ``max_step=None`` (tracking from a nearby state): a step larger than 0.5 rad means the
        seed is in another basin, and the attempt ends. Otherwise steps are scaled down to
        ``max_step`` and the search goes on, as it must from a random seed.
        """
        scene = self.scene
        lo, hi = scene.limits.lower, scene.limits.upper
        q = np.clip(np.array(seed, dtype=float), lo, hi)
        self._last_iterate = q
        movable = scene.movable_positions()
        for _ in range(iterations):
            pose = scene.forward(q)
            error = np.concatenate([target[:3, 3] - pose[:3, 3], rotation_vector(target[:3, :3] @ pose[:3, :3].T)])
            if np.linalg.norm(error[:3]) < tolerance * 0.1 and np.linalg.norm(error[3:]) < 1e-4:
                return np.asarray(q, dtype=float)
            jac = self._jacobian(q, movable)
            free = np.ones(len(q), dtype=bool)
            step = np.zeros(len(q))
            for _ in range(len(q)):
                # Damped least squares on the joints not pinned at a limit: well-defined near
                # singularities, and a 6x6 solve is cheap.
                jf = jac[:, free]
                step = np.zeros(len(q))
                step[free] = jf.T @ np.linalg.solve(jf @ jf.T + NEWTON_DAMPING * np.eye(6), error)
                pinned = free & (((q <= lo + AT_LIMIT) & (step < 0)) | ((q >= hi - AT_LIMIT) & (step > 0)))
                if not pinned.any():
                    break
                free &= ~pinned
                if not free.any():
                    return None
            largest = float(np.max(np.abs(step)))
            if max_step is None:
                if largest > 0.5:  # far from the seed's basin: leave it to the global search
                    return None
            elif largest > max_step:
                step *= max_step / largest
            q = np.clip(q + step, lo, hi)
            self._last_iterate = q
        return None

    def _solve_from(
        self, target: np.ndarray, seed: np.ndarray, near: np.ndarray, tolerance: float
    ) -> tuple[np.ndarray | None, np.ndarray | None]:
        """A solution within the limits from ``seed`` (or None), and the answer of pybullet's
        solver, which ignores the limits, when it was asked (or None): what tells a pose out of
        reach from one reachable only outside the limits."""
        raw = None
        q = self._newton(target, seed, tolerance, iterations=NEWTON_ITERATIONS, max_step=None)
        if q is None:
            q = self._newton(target, seed, tolerance, iterations=GLOBAL_ITERATIONS, max_step=GLOBAL_STEP)
        if q is None:
            raw = self._unconstrained(target, seed)
            wrapped = self.wrap_into_limits(raw, near)
            if wrapped is not None:
                q = self._newton(target, wrapped, tolerance, iterations=GLOBAL_ITERATIONS, max_step=GLOBAL_STEP)
        if q is not None:
            # The same arm shape a whole turn nearer to where the arm is costs less motion.
            nearer = self.wrap_into_limits(q, near)
            q = q if nearer is None else nearer
        return q, raw

    def _unconstrained(self, target: np.ndarray, seed: np.ndarray) -> np.ndarray:
        """pybullet's damped solver, which ignores the limits (its null-space mode converges worse)."""
        scene = self.scene
        scene.set_joints(seed)
        pos, quat = to_xyz_quat(target)
        raw = p.calculateInverseKinematics(
            scene.robot,
            scene.tool_index,
            pos.tolist(),
            quat.tolist(),
            maxNumIterations=self.iterations,
            residualThreshold=self.residual,
            physicsClientId=scene.client,
        )
        return np.array([raw[i] for i in scene.ik_slots])

    def _pose_error(self, q: np.ndarray, target: np.ndarray) -> tuple[float, float]:
        """How far the tool at ``q`` is from ``target``: position (m), orientation (rad)."""
        pose = self.scene.forward(q)
        return float(np.linalg.norm(pose[:3, 3] - target[:3, 3])), angle_between(pose, target)

    def _beyond_limits(self, raw: np.ndarray, target: np.ndarray, tolerance: float) -> tuple[LimitExcess, ...]:
        """If pybullet's answer ``raw`` reaches ``target``, its joints outside their range even a
        whole turn either way: what keeps it from being a solution; none when it does not reach."""
        position, orientation = self._pose_error(raw, target)
        if position > max(5 * tolerance, UNCONSTRAINED_POSITION) or orientation > UNCONSTRAINED_ORIENTATION:
            return ()
        lo, hi = self.scene.limits.lower, self.scene.limits.upper
        out = []
        for i, name in enumerate(self.scene.joint_names):
            # The value nearest to the range, over whole turns: what the joint would need.
            candidates = [raw[i] + 2 * np.pi * k for k in range(-3, 4)]
            value = min(candidates, key=lambda c: max(lo[i] - c, c - hi[i], 0.0))
            if value < lo[i] - 1e-6:
                out.append(LimitExcess(name, float(value), float(lo[i]), upper=False))
            elif value > hi[i] + 1e-6:
                out.append(LimitExcess(name, float(value), float(hi[i]), upper=True))
        return tuple(out)

    def wrap_into_limits(self, q: np.ndarray, near: np.ndarray) -> np.ndarray | None:
        """Add multiples of 2*pi per joint to land inside the limits, nearest to ``near``."""
        lo, hi = self.scene.limits.lower, self.scene.limits.upper
        out = np.empty_like(q)
        for i, (value, ref) in enumerate(zip(q, near, strict=False)):
            k = np.round((ref - value) / (2 * np.pi))
            candidates = [value + 2 * np.pi * (k + d) for d in (0, -1, 1, -2, 2)]
            inside = [c for c in candidates if lo[i] - 1e-9 <= c <= hi[i] + 1e-9]
            if not inside:
                return None
            out[i] = min(inside, key=lambda c: abs(c - ref))
        return out
