"""Timing a joint path within velocity and acceleration limits.

The path is split where its direction turns sharply (the corners of a simplified OMPL path);
each piece gets a trapezoidal speed profile along a path parameter in which speed 1 means the
limiting joint moves at its velocity limit, so no joint exceeds its limit anywhere. Pieces
start and end at rest, so the corners are taken without an acceleration spike; gentle bends
(a Cartesian line mapped into joint space) are passed through at speed.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TimedPath", "time_parameterize"]

#: Directions that turn by more than this (radians, in velocity-scaled joint space) end a piece.
CORNER_ANGLE = np.radians(20.0)


@dataclass(frozen=True)
class TimedPath:
    times: np.ndarray  # (n,)
    positions: np.ndarray  # (n, dof)
    velocities: np.ndarray  # (n, dof)

    @property
    def duration(self) -> float:
        return float(self.times[-1]) if len(self.times) else 0.0


def _trapezoid(length: float, v_max: float, a_max: float) -> tuple[float, float, float]:
    """(accel time, cruise time, peak speed) of a rest-to-rest profile over ``length``."""
    t_acc = v_max / a_max
    if a_max * t_acc * t_acc >= length:  # never reaches v_max: triangular profile
        t_acc = float(np.sqrt(length / a_max))
        return t_acc, 0.0, a_max * t_acc
    return t_acc, (length - a_max * t_acc * t_acc) / v_max, v_max


def _position_at(t: float, t_acc: float, t_cruise: float, peak: float, a: float) -> tuple[float, float]:
    """Arc position and speed at time ``t`` of a trapezoid."""
    if t <= t_acc:
        return 0.5 * a * t * t, a * t
    d_acc = 0.5 * a * t_acc * t_acc
    if t <= t_acc + t_cruise:
        return d_acc + peak * (t - t_acc), peak
    td = min(t - t_acc - t_cruise, t_acc)
    return d_acc + peak * t_cruise + peak * td - 0.5 * a * td * td, max(0.0, peak - a * td)


def _pieces(points: np.ndarray, scale: np.ndarray) -> list[np.ndarray]:
    cuts = [0]
    for i in range(1, len(points) - 1):
        d0 = (points[i] - points[i - 1]) / scale
        d1 = (points[i + 1] - points[i]) / scale
        n0, n1 = np.linalg.norm(d0), np.linalg.norm(d1)
        if n0 > 0 and n1 > 0 and np.arccos(np.clip(d0 @ d1 / (n0 * n1), -1, 1)) > CORNER_ANGLE:
            cuts.append(i)
    cuts.append(len(points) - 1)
    return [points[a : b + 1] for a, b in zip(cuts, cuts[1:], strict=False)]


def time_parameterize(
    path: list[np.ndarray] | np.ndarray,
    max_velocity: np.ndarray,
    max_acceleration: float,
    *,
    velocity_scaling: float = 1.0,
    sample_period: float = 0.05,
) -> TimedPath:
    """Times, positions and velocities along ``path``, sampled every ``sample_period`` s.

    Args:
        path: joint vectors; consecutive duplicates are dropped.
        max_velocity: per-joint velocity limits (rad/s).
        max_acceleration: per-joint acceleration limit (rad/s^2).
        velocity_scaling: fraction of ``max_velocity`` to use (0, 1].
    """
    points = np.asarray(path, dtype=float)
    keep = [0] + [i for i in range(1, len(points)) if np.max(np.abs(points[i] - points[i - 1])) > 1e-9]
    points = points[keep]
    if len(points) < 2:
        dof = points.shape[1]
        return TimedPath(np.zeros(1), points[:1].copy(), np.zeros((1, dof)))
    vmax = np.asarray(max_velocity, dtype=float) * velocity_scaling
    times, positions, velocities = [0.0], [points[0]], [np.zeros(points.shape[1])]
    t0 = 0.0
    for piece in _pieces(points, vmax):
        # Parameter s: time at full speed of the limiting joint, per segment.
        seg = np.diff(piece, axis=0)
        seg_len = np.max(np.abs(seg) / vmax, axis=1)
        s_nodes = np.concatenate([[0.0], np.cumsum(seg_len)])
        length = float(s_nodes[-1])
        # ds/dt <= 1 keeps velocities in limits; joint acceleration = dq/ds * s'', so s'' is
        # bounded by the fastest joint rate dq/ds along this piece.
        moving = seg_len > 0
        rate = float(np.max(np.abs(seg[moving]) / seg_len[moving, None]))
        a_s = max_acceleration / rate
        t_acc, t_cruise, peak = _trapezoid(length, 1.0, a_s)
        duration = 2 * t_acc + t_cruise
        n = max(2, int(np.ceil(duration / sample_period)) + 1)
        for t in np.linspace(0.0, duration, n)[1:]:
            s, sdot = _position_at(float(t), t_acc, t_cruise, peak, a_s)
            s = min(s, length)
            k = int(np.clip(np.searchsorted(s_nodes, s, side="right") - 1, 0, len(seg) - 1))
            frac = (s - s_nodes[k]) / seg_len[k] if seg_len[k] > 0 else 1.0
            positions.append(piece[k] + seg[k] * frac)
            velocities.append(seg[k] / seg_len[k] * sdot if seg_len[k] > 0 else np.zeros_like(seg[k]))
            times.append(t0 + float(t))
        positions[-1] = piece[-1]
        velocities[-1] = np.zeros(points.shape[1])
        t0 += duration
    return TimedPath(np.array(times), np.array(positions), np.array(velocities))
