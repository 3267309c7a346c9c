"""Checked reading of the 3D view's inputs, and the contract's value shapes (poses, colours, shapes).

Everything the view's data is made from crosses the link as plain data and is hostile until
checked: each reader here takes a value and ``where`` it is (``scene.bodies[2].shapes[0].size``)
and returns it typed, or raises :class:`SpatialDataError` naming that place and what was
expected. :mod:`console.spatial_scene` (the scene document), :mod:`console.spatial_updates`
(the live updates) and :mod:`console.spatial_world` read with these.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

CONTRACT_VERSION = 1
DOCUMENT_FRAME = "world"
#: The paper's colours: display objects green, waypoints teal (the view draws both).
DISPLAY_OBJECT_COLOR = (0.2, 0.9, 0.3, 0.45)
#: A target panel floats this far off a curved hull (the simulation draws it so).
TARGET_RAISE = 0.015

Json = dict[str, Any]


class SpatialDataError(ValueError):
    """Input the view's data cannot be made from; ``where`` names the bad value."""

    def __init__(self, where: str, message: str) -> None:
        super().__init__(f"{where}: {message}")
        self.where = where


# --------------------------------------------------------------------------- checked reading


def mapping(value: Any, where: str) -> Mapping[str, Any]:
    if not isinstance(value, Mapping):
        raise SpatialDataError(where, f"expected a mapping, got {type(value).__name__}")
    return value


def sequence(value: Any, where: str) -> Sequence[Any]:
    if not isinstance(value, (list, tuple)):
        raise SpatialDataError(where, f"expected a list, got {type(value).__name__}")
    return value


def required(data: Mapping[str, Any], key: str, where: str) -> Any:
    if key not in data:
        raise SpatialDataError(f"{where}.{key}", "missing required key")
    return data[key]


def text(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value:
        raise SpatialDataError(where, f"expected a non-empty string, got {value!r}")
    return value


def number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SpatialDataError(where, f"expected a finite number, got {value!r}")
    return float(value)


def numbers(value: Any, n: int, where: str) -> list[float]:
    items = sequence(value, where)
    if len(items) != n:
        raise SpatialDataError(where, f"expected {n} numbers, got {len(items)}")
    return [number(v, f"{where}[{i}]") for i, v in enumerate(items)]


def names(value: Any, where: str) -> list[str]:
    return [text(v, f"{where}[{i}]") for i, v in enumerate(sequence(value, where))]


# --------------------------------------------------------------------------------- poses


def quat_from_rpy(roll: float, pitch: float, yaw: float) -> list[float]:
    cr, sr = math.cos(roll / 2), math.sin(roll / 2)
    cp, sp = math.cos(pitch / 2), math.sin(pitch / 2)
    cy, sy = math.cos(yaw / 2), math.sin(yaw / 2)
    return [
        sr * cp * cy - cr * sp * sy,
        cr * sp * cy + sr * cp * sy,
        cr * cp * sy - sr * sp * cy,
        cr * cp * cy + sr * sp * sy,
    ]


def pose(xyz: Sequence[float] = (0.0, 0.0, 0.0), rpy: Sequence[float] = (0.0, 0.0, 0.0)) -> Json:
    """A contract pose from position and fixed-axis roll-pitch-yaw."""
    return {"xyz": [float(v) for v in xyz], "quat": quat_from_rpy(*(float(v) for v in rpy))}


def compose(a: Json, b: Json) -> Json:
    """Pose ``b`` (given in the frame whose pose is ``a``) in ``a``'s own frame: a * b."""
    ax, ay, az, aw = a["quat"]
    bx, by, bz, bw = b["quat"]
    quat = [
        aw * bx + ax * bw + ay * bz - az * by,
        aw * by - ax * bz + ay * bw + az * bx,
        aw * bz + ax * by - ay * bx + az * bw,
        aw * bw - ax * bx - ay * by - az * bz,
    ]
    # b's position rotated by a's quaternion: v + 2w(q x v) + 2q x (q x v)
    vx, vy, vz = b["xyz"]
    tx, ty, tz = 2 * (ay * vz - az * vy), 2 * (az * vx - ax * vz), 2 * (ax * vy - ay * vx)
    rotated = [
        vx + aw * tx + (ay * tz - az * ty),
        vy + aw * ty + (az * tx - ax * tz),
        vz + aw * tz + (ax * ty - ay * tx),
    ]
    return {"xyz": [p + r for p, r in zip(a["xyz"], rotated, strict=True)], "quat": quat}


def scene_pose(value: Any, where: str) -> Json:
    """``{xyz, rpy}`` of a scene file (both optional, zeros by default)."""
    if value is None:
        return pose()
    data = mapping(value, where)
    xyz = numbers(data.get("xyz", [0, 0, 0]), 3, f"{where}.xyz")
    rpy = numbers(data.get("rpy", [0, 0, 0]), 3, f"{where}.rpy")
    return pose(xyz, rpy)


def ros_pose(value: Any, where: str) -> Json:
    """geometry_msgs/Pose as rosbridge JSON; the quaternion is normalized (a zero one is an error)."""
    data = mapping(value, where)
    position = mapping(required(data, "position", where), f"{where}.position")
    orientation = mapping(required(data, "orientation", where), f"{where}.orientation")
    xyz = [number(required(position, k, f"{where}.position"), f"{where}.position.{k}") for k in "xyz"]
    quat = [number(required(orientation, k, f"{where}.orientation"), f"{where}.orientation.{k}") for k in "xyzw"]
    norm = math.sqrt(sum(q * q for q in quat))
    if norm < 1e-9:
        raise SpatialDataError(f"{where}.orientation", "the quaternion is zero")
    return {"xyz": xyz, "quat": [q / norm for q in quat]}


def rgba(value: Any, where: str) -> list[float]:
    rgba = numbers(value, 4, where)
    if any(not 0.0 <= c <= 1.0 for c in rgba):
        raise SpatialDataError(where, f"colour components must be within 0..1, got {rgba}")
    return rgba


# --------------------------------------------------------------------------------- shapes


def box(size: Sequence[float], rgba: Sequence[float], at: Json | None = None) -> Json:
    return {"type": "box", "size": list(size), "rgba": list(rgba), "pose": at or pose()}


def cylinder(radius: float, length: float, rgba: Sequence[float], at: Json | None = None) -> Json:
    """A cylinder along its own z axis (URDF's and pybullet's convention)."""
    return {"type": "cylinder", "radius": radius, "length": length, "rgba": list(rgba), "pose": at or pose()}


def scene_shape(value: Any, rgba: list[float], where: str) -> Json:
    data = mapping(value, where)
    kind = required(data, "type", where)
    at = pose(
        numbers(data.get("xyz", [0, 0, 0]), 3, f"{where}.xyz"), numbers(data.get("rpy", [0, 0, 0]), 3, f"{where}.rpy")
    )
    if kind == "box":
        size = numbers(required(data, "size", where), 3, f"{where}.size")
        if any(v <= 0 for v in size):
            raise SpatialDataError(f"{where}.size", f"sizes must be positive, got {size}")
        return box(size, rgba, at)
    if kind == "cylinder":
        radius = number(required(data, "radius", where), f"{where}.radius")
        length = number(required(data, "length", where), f"{where}.length")
        if radius <= 0 or length <= 0:
            raise SpatialDataError(where, f"radius and length must be positive, got {radius}, {length}")
        return cylinder(radius, length, rgba, at)
    raise SpatialDataError(f"{where}.type", f"unknown shape type {kind!r}; expected box or cylinder")


def stamp(header: Any, where: str) -> float:
    if header is None:
        return 0.0
    stamp = mapping(mapping(header, where).get("stamp", {}), f"{where}.stamp")
    return (
        number(stamp.get("sec", 0), f"{where}.stamp.sec")
        + number(stamp.get("nanosec", 0), f"{where}.stamp.nanosec") * 1e-9
    )


def duration(value: Any, where: str) -> float:
    d = mapping(value, where)
    return number(d.get("sec", 0), f"{where}.sec") + number(d.get("nanosec", 0), f"{where}.nanosec") * 1e-9
