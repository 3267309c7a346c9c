"""Joint trajectories for the simulated arm controller: validated whole before any motion.

A controller that starts moving and then finds point 17 out of limits has already moved the arm,
so every check (names, finite numbers, limits, velocities, time stamps, start point) runs here,
before the simulation accepts the trajectory. Errors carry the action's error code and say
which point and joint is wrong and what the limit is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["JointLimit", "Trajectory", "TrajectoryError", "ErrorCode", "validate_trajectory"]

#: Relative slack on velocity limits, so a time-optimal parameterisation exactly at the limit passes.
VELOCITY_SLACK = 1e-3
#: How far (rad) a t=0 first point may be from the current position: a controller never jumps.
START_TOLERANCE = 0.01


class ErrorCode:
    """Result codes of caretaker_sim_msgs/action/FollowJointTrajectory (kept in one place)."""

    SUCCESSFUL = 0
    INVALID_GOAL = -1
    INVALID_JOINTS = -2
    PATH_TOLERANCE_VIOLATED = -4
    GOAL_TOLERANCE_VIOLATED = -5
    COLLISION = -6
    HALTED = -7


class TrajectoryError(ValueError):
    """A trajectory the controller refuses; ``code`` is the action result's error_code."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


@dataclass(frozen=True)
class JointLimit:
    lower: float
    upper: float
    velocity: float


@dataclass(frozen=True)
class Trajectory:
    """A validated trajectory over all arm joints (controller order), starting at t = 0.

    Points are (time, positions, velocities or None). Joints the goal did not name hold their
    current position. Between points the motion is a cubic Hermite spline when every point has
    velocities, otherwise linear.
    """

    joint_names: tuple[str, ...]
    times: tuple[float, ...]
    positions: tuple[tuple[float, ...], ...]
    velocities: tuple[tuple[float, ...], ...] | None

    @property
    def duration(self) -> float:
        return self.times[-1]

    @property
    def final(self) -> tuple[float, ...]:
        return self.positions[-1]

    def sample(self, t: float) -> tuple[tuple[float, ...], tuple[float, ...]]:
        """Desired positions and velocities at time ``t`` (clamped to the trajectory's span)."""
        if t >= self.times[-1]:
            return self.positions[-1], tuple(0.0 for _ in self.joint_names)
        t = max(t, 0.0)
        i = 0
        while self.times[i + 1] < t:
            i += 1
        t0, t1 = self.times[i], self.times[i + 1]
        h = t1 - t0
        s = (t - t0) / h
        q0, q1 = self.positions[i], self.positions[i + 1]
        if self.velocities is None:
            return (
                tuple(a + (b - a) * s for a, b in zip(q0, q1, strict=False)),
                tuple((b - a) / h for a, b in zip(q0, q1, strict=False)),
            )
        v0, v1 = self.velocities[i], self.velocities[i + 1]
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        d00, d10, d01, d11 = (6 * s**2 - 6 * s) / h, 3 * s**2 - 4 * s + 1, (-6 * s**2 + 6 * s) / h, 3 * s**2 - 2 * s
        pos = tuple(
            h00 * a + h10 * h * va + h01 * b + h11 * h * vb for a, b, va, vb in zip(q0, q1, v0, v1, strict=False)
        )
        vel = tuple(d00 * a + d10 * va + d01 * b + d11 * vb for a, b, va, vb in zip(q0, q1, v0, v1, strict=False))
        return pos, vel


def _finite(values: list[float]) -> bool:
    return all(math.isfinite(v) for v in values)


def validate_trajectory(
    joint_names: list[str],
    points: list[tuple[float, list[float], list[float]]],
    *,
    limits: dict[str, JointLimit],
    controller_joints: tuple[str, ...],
    current: tuple[float, ...],
    other_joints: tuple[str, ...] = (),
) -> Trajectory:
    """Check a goal and turn it into a :class:`Trajectory` over all ``controller_joints``.

    Args:
        joint_names: the goal's joint names (any order, any subset of the controller's joints).
        points: (time_from_start in s, positions, velocities (may be empty)) per point.
        limits: position and velocity limits per joint (from the URDF).
        controller_joints: the joints this controller moves, in its order.
        current: current positions of ``controller_joints``.
        other_joints: joints the robot has but this controller does not move (named in errors).

    Raises:
        TrajectoryError: with the action error code and what to fix.
    """
    if not joint_names:
        raise TrajectoryError(ErrorCode.INVALID_JOINTS, "trajectory names no joints")
    for name in joint_names:
        if name in other_joints:
            raise TrajectoryError(
                ErrorCode.INVALID_JOINTS,
                f"joint {name!r} is not an arm joint (use the gripper service); "
                f"arm joints are {list(controller_joints)}",
            )
        if name not in controller_joints:
            raise TrajectoryError(
                ErrorCode.INVALID_JOINTS, f"unknown joint {name!r}; arm joints are {list(controller_joints)}"
            )
    if len(set(joint_names)) != len(joint_names):
        raise TrajectoryError(ErrorCode.INVALID_JOINTS, f"joint names repeat: {joint_names}")
    if not points:
        raise TrajectoryError(ErrorCode.INVALID_GOAL, "trajectory has no points")
    n = len(joint_names)
    index = {name: controller_joints.index(name) for name in joint_names}
    have_velocities = all(len(v) > 0 for _, _, v in points)
    times: list[float] = []
    full_positions: list[tuple[float, ...]] = []
    full_velocities: list[tuple[float, ...]] = []
    previous_time = -math.inf
    for k, (t, q, v) in enumerate(points):
        if not math.isfinite(t):
            raise TrajectoryError(ErrorCode.INVALID_GOAL, f"point {k}: time_from_start is {t}")
        if t < 0:
            raise TrajectoryError(ErrorCode.INVALID_GOAL, f"point {k}: time_from_start {t:.6f} s is negative")
        if t <= previous_time:
            raise TrajectoryError(
                ErrorCode.INVALID_GOAL,
                f"point {k}: time_from_start {t:.6f} s is not after point {k - 1} ({previous_time:.6f} s); "
                "time stamps must increase",
            )
        previous_time = t
        if len(q) != n:
            raise TrajectoryError(ErrorCode.INVALID_GOAL, f"point {k}: {len(q)} positions for {n} joints")
        if v and len(v) != n:
            raise TrajectoryError(ErrorCode.INVALID_GOAL, f"point {k}: {len(v)} velocities for {n} joints")
        if not _finite(list(q)) or not _finite(list(v)):
            bad = [joint_names[i] for i in range(n) if not math.isfinite(q[i]) or (v and not math.isfinite(v[i]))]
            raise TrajectoryError(ErrorCode.INVALID_GOAL, f"point {k}: non-finite value (NaN or inf) for joints {bad}")
        for i, name in enumerate(joint_names):
            lim = limits[name]
            if not lim.lower <= q[i] <= lim.upper:
                raise TrajectoryError(
                    ErrorCode.INVALID_GOAL,
                    f"point {k}: joint {name} position {q[i]:.4f} rad "
                    f"is outside its limits [{lim.lower:.4f}, {lim.upper:.4f}]",
                )
            if v and abs(v[i]) > lim.velocity * (1 + VELOCITY_SLACK):
                raise TrajectoryError(
                    ErrorCode.INVALID_GOAL,
                    f"point {k}: joint {name} velocity {v[i]:.4f} rad/s exceeds its limit {lim.velocity:.4f} rad/s",
                )
        full_q = list(current)
        full_v = [0.0] * len(controller_joints)
        for i, name in enumerate(joint_names):
            full_q[index[name]] = q[i]
            if have_velocities:
                full_v[index[name]] = v[i]
        times.append(t)
        full_positions.append(tuple(full_q))
        full_velocities.append(tuple(full_v))
    if times[0] == 0.0:
        worst = max(range(len(current)), key=lambda j: abs(full_positions[0][j] - current[j]))
        if abs(full_positions[0][worst] - current[worst]) > START_TOLERANCE:
            raise TrajectoryError(
                ErrorCode.INVALID_GOAL,
                f"point 0 at t=0 is {abs(full_positions[0][worst] - current[worst]):.4f} rad "
                "away from the current position of "
                f"{controller_joints[worst]}; start at the current state or give the first point a time > 0",
            )
    else:
        # The controller starts from where the arm is: that is the implicit point at t = 0.
        times.insert(0, 0.0)
        full_positions.insert(0, tuple(current))
        full_velocities.insert(0, tuple(0.0 for _ in current))
    for k in range(1, len(times)):
        dt = times[k] - times[k - 1]
        for j, name in enumerate(controller_joints):
            speed = abs(full_positions[k][j] - full_positions[k - 1][j]) / dt
            lim = limits[name].velocity
            if speed > lim * (1 + VELOCITY_SLACK):
                label = "the current position" if k == 1 and points[0][0] > 0 else "the previous point"
                raise TrajectoryError(
                    ErrorCode.INVALID_GOAL,
                    f"joint {name} must move {abs(full_positions[k][j] - full_positions[k - 1][j]):.4f} rad "
                    f"from {label} in {dt:.4f} s "
                    f"({speed:.3f} rad/s), over its velocity limit {lim:.4f} rad/s",
                )
    return Trajectory(
        tuple(controller_joints),
        tuple(times),
        tuple(full_positions),
        tuple(full_velocities) if have_velocities else None,
    )
