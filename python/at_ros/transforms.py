"""Rigid transforms as 4x4 numpy matrices, with the conversions AT files and ROS messages need.

The original AT package converted `rpy` with tf's createQuaternionMsgFromRollPitchYaw, i.e.
fixed axes X, then Y, then Z (R = Rz(yaw) Ry(pitch) Rx(roll)); quaternions are ROS-ordered
(x, y, z, w). Everything here keeps those conventions so template files mean what they meant.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

__all__ = [
    "from_xyz_rpy",
    "from_xyz_quat",
    "to_xyz_quat",
    "to_xyz_rpy",
    "quat_from_rpy",
    "rpy_from_matrix",
    "matrix_from_quat",
    "quat_from_matrix",
    "invert",
    "angle_between",
    "pose_text",
]


def quat_from_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    """Quaternion (x, y, z, w) of fixed-axis roll-pitch-yaw."""
    cr, sr = np.cos(roll / 2), np.sin(roll / 2)
    cp, sp = np.cos(pitch / 2), np.sin(pitch / 2)
    cy, sy = np.cos(yaw / 2), np.sin(yaw / 2)
    return np.array(
        [
            sr * cp * cy - cr * sp * sy,
            cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy,
            cr * cp * cy + sr * sp * sy,
        ]
    )


def matrix_from_quat(q: Sequence[float] | np.ndarray) -> np.ndarray:
    """3x3 rotation of a quaternion (x, y, z, w); the quaternion need not be normalized."""
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_from_matrix(r: np.ndarray) -> np.ndarray:
    """Quaternion (x, y, z, w), w >= 0, of a 3x3 rotation (Shepperd's method, stable for all angles)."""
    m = np.asarray(r, dtype=float)[:3, :3]
    trace = m[0, 0] + m[1, 1] + m[2, 2]
    if trace > 0:
        s = 2.0 * np.sqrt(trace + 1.0)
        q = [(m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, 0.25 * s]
    elif m[0, 0] > m[1, 1] and m[0, 0] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = [0.25 * s, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s]
    elif m[1, 1] > m[2, 2]:
        s = 2.0 * np.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = [(m[0, 1] + m[1, 0]) / s, 0.25 * s, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = [(m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, 0.25 * s, (m[1, 0] - m[0, 1]) / s]
    quat = np.array(q)
    quat /= np.linalg.norm(quat)
    return -quat if quat[3] < 0 else quat


def rpy_from_matrix(r: np.ndarray) -> tuple[float, float, float]:
    """Fixed-axis roll, pitch, yaw of a rotation matrix (inverse of quat_from_rpy)."""
    m = np.asarray(r, dtype=float)[:3, :3]
    pitch = float(np.arcsin(np.clip(-m[2, 0], -1.0, 1.0)))
    if abs(m[2, 0]) < 1 - 1e-9:
        roll = float(np.arctan2(m[2, 1], m[2, 2]))
        yaw = float(np.arctan2(m[1, 0], m[0, 0]))
    else:  # gimbal lock: only roll +- yaw is defined; put it all in yaw
        roll = 0.0
        yaw = float(np.arctan2(-m[0, 1], m[1, 1]))
    return roll, pitch, yaw


def from_xyz_rpy(xyz: Sequence[float], rpy: Sequence[float]) -> np.ndarray:
    """4x4 transform of a translation and fixed-axis roll-pitch-yaw."""
    t = np.eye(4)
    t[:3, :3] = matrix_from_quat(quat_from_rpy(*rpy))
    t[:3, 3] = xyz
    return t


def from_xyz_quat(xyz: Sequence[float] | np.ndarray, quat: Sequence[float] | np.ndarray) -> np.ndarray:
    """4x4 transform of a translation and a quaternion (x, y, z, w)."""
    t = np.eye(4)
    t[:3, :3] = matrix_from_quat(quat)
    t[:3, 3] = xyz
    return t


def to_xyz_quat(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Translation and quaternion (x, y, z, w) of a 4x4 transform."""
    return np.array(t[:3, 3], dtype=float), quat_from_matrix(t[:3, :3])


def to_xyz_rpy(t: np.ndarray) -> tuple[np.ndarray, tuple[float, float, float]]:
    """Translation and fixed-axis roll-pitch-yaw of a 4x4 transform."""
    return np.array(t[:3, 3], dtype=float), rpy_from_matrix(t[:3, :3])


def invert(t: np.ndarray) -> np.ndarray:
    """Inverse of a rigid 4x4 transform (cheaper and exacter than np.linalg.inv)."""
    inv = np.eye(4)
    inv[:3, :3] = t[:3, :3].T
    inv[:3, 3] = -t[:3, :3].T @ t[:3, 3]
    return inv


def angle_between(a: np.ndarray, b: np.ndarray) -> float:
    """Rotation angle (radians) between the orientations of two transforms."""
    r = a[:3, :3].T @ b[:3, :3]
    return float(np.arccos(np.clip((np.trace(r) - 1.0) / 2.0, -1.0, 1.0)))


def pose_text(t: np.ndarray) -> str:
    """A 4x4 transform as an operator reads it: metres to the millimetre, fixed-axis
    roll/pitch/yaw to a tenth of a degree ("x=0.912 y=-0.130 z=1.204 m, roll/pitch/yaw=180.0/0.0/90.0 deg")."""

    def shown(value: float, digits: int) -> str:
        return f"{round(value, digits) + 0.0:.{digits}f}"  # + 0.0: a rounded -0.0 shows as 0.0

    xyz, rpy = to_xyz_rpy(t)
    x, y, z = (shown(float(v), 3) for v in xyz)
    roll, pitch, yaw = (shown(float(np.degrees(a)), 1) for a in rpy)
    return f"x={x} y={y} z={z} m, roll/pitch/yaw={roll}/{pitch}/{yaw} deg"
