"""Where an object is, from the fiducial markers declared on it, in one camera image.

Pure OpenCV and numpy, no ROS: the node (``perception_node``) feeds it an image, the camera's
calibration and the markers the world model declares on the object, and gets a pose or a
refusal in words. A refusal is the answer whenever the image does not fully support a pose:
a declared marker not seen (covered, out of view, another id in its place), a marker cut by the
image edge, an id seen twice, or corners that do not fit one rigid pose within the tolerance.
A guess is never returned, because a registration from it would move the robot.

All corners of all the object's markers are solved for jointly (SQPnP, then Levenberg-Marquardt):
two markers a few tens of centimetres apart fix the orientation far better than one marker's
four corners (whose tilt is ambiguous when seen head-on). Corners are refined with OpenCV's
AprilTag method, which fits the border's edges and so stays sub-pixel on hard-edged images.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import cv2
import numpy as np

__all__ = ["DEFAULT_TOLERANCE_PX", "Calibration", "Located", "MarkerOnObject", "NotLocated", "detect", "locate"]

#: A marker with a corner closer than this to the image border (px) may be partly out of view:
#: one whose border runs off the image is still detected, its corners put up to 5 px inside the
#: image (tests/perception/test_locate_image.py), and a pose from them is off.
EDGE_PX = 8.0
#: Largest reprojection error (px RMS) accepted when a request gives none. Clean views of the
#: shipped markers fit to 0.05-0.5 px (bench/perception_bench.py); a filter marker whose white
#: margin the handle darkens fits to 0.8 px and is off by 7 mm and 2.6 deg: refused.
DEFAULT_TOLERANCE_PX = 0.6


@dataclass(frozen=True)
class MarkerOnObject:
    """A marker declared on the object: its id, its side (m) and its pose in the object's frame
    (4x4; z out of the printed face, x right, y up as the marker reads)."""

    id: int
    size: float
    pose: np.ndarray


@dataclass(frozen=True)
class Calibration:
    """A pinhole camera without distortion, as ``sensor_msgs/CameraInfo`` gives it."""

    width: int
    height: int
    matrix: np.ndarray  # 3x3 K


@dataclass(frozen=True)
class Located:
    """The object's pose in the camera's optical frame, and how well the image supports it."""

    camera_to_object: np.ndarray  # 4x4
    residual_px: float  # RMS over every corner used
    markers: tuple[int, ...]


class NotLocated(Exception):
    """The image does not support a pose; the message says why in words."""


@functools.cache
def _detector(dictionary: str) -> cv2.aruco.ArucoDetector:
    parameters = cv2.aruco.DetectorParameters()
    parameters.cornerRefinementMethod = cv2.aruco.CORNER_REFINE_APRILTAG
    return cv2.aruco.ArucoDetector(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)), parameters)


def detect(gray: np.ndarray, dictionary: str) -> list[tuple[int, np.ndarray]]:
    """Every marker of ``dictionary`` in an 8-bit grey image: (id, 4x2 corners in px), corners in
    the marker's order (top-left, top-right, bottom-right, bottom-left as it reads)."""
    corners, ids, _ = _detector(dictionary).detectMarkers(gray)
    if ids is None:
        return []
    return [(int(i), c.reshape(4, 2).astype(np.float64)) for i, c in zip(ids.ravel(), corners, strict=True)]


def _corners_on_object(marker: MarkerOnObject) -> np.ndarray:
    """The marker's four corners in the object's frame, in the order ``detect`` gives them."""
    h = marker.size / 2
    square = np.array([[-h, h, 0.0, 1.0], [h, h, 0.0, 1.0], [h, -h, 0.0, 1.0], [-h, -h, 0.0, 1.0]])
    corners: np.ndarray = (marker.pose @ square.T).T[:, :3]
    return corners


def _ids(ids: list[int] | set[int]) -> str:
    return ", ".join(str(i) for i in sorted(ids)) or "none"


def locate(
    gray: np.ndarray,
    calibration: Calibration,
    dictionary: str,
    markers: list[MarkerOnObject],
    tolerance_px: float,
) -> Located:
    """The object that carries ``markers``, located in ``gray``.

    Raises:
        NotLocated: the image does not support a pose (the message says why).
    """
    if not markers:
        raise NotLocated("no markers are declared on it")
    seen = detect(gray, dictionary)
    declared = {m.id: m for m in markers}
    found: dict[int, np.ndarray] = {}
    for marker_id, corners in seen:
        if marker_id not in declared:
            continue
        if marker_id in found:
            raise NotLocated(f"marker {marker_id} is seen twice: which one is the object's is not known")
        found[marker_id] = corners
    others = {i for i, _ in seen} - declared.keys()
    missing = declared.keys() - found.keys()
    if missing:
        if found:
            what = f"only marker(s) {_ids(set(found))} of {_ids(set(declared))} are seen"
        else:
            what = f"none of its markers ({_ids(set(declared))}) is seen"
        raise NotLocated(f"{what}; other markers in view: {_ids(others)}")
    for marker_id, corners in found.items():
        x, y = corners[:, 0], corners[:, 1]
        if (
            x.min() < EDGE_PX
            or y.min() < EDGE_PX
            or x.max() > calibration.width - 1 - EDGE_PX
            or y.max() > calibration.height - 1 - EDGE_PX
        ):
            raise NotLocated(f"marker {marker_id} is cut by the image edge (partly out of view)")
    used = tuple(sorted(found))
    object_points = np.vstack([_corners_on_object(declared[i]) for i in used])
    image_points = np.vstack([found[i] for i in used])
    ok, rvec, tvec = cv2.solvePnP(object_points, image_points, calibration.matrix, None, flags=cv2.SOLVEPNP_SQPNP)
    if not ok:
        raise NotLocated(f"no pose fits the corners of marker(s) {_ids(set(used))}")
    rvec, tvec = cv2.solvePnPRefineLM(object_points, image_points, calibration.matrix, None, rvec, tvec)
    projected, _ = cv2.projectPoints(object_points, rvec, tvec, calibration.matrix, None)
    residual = float(np.sqrt(np.mean(np.sum((projected.reshape(-1, 2) - image_points) ** 2, axis=1))))
    if residual > tolerance_px:
        raise NotLocated(
            f"the corners of marker(s) {_ids(set(used))} fit a pose only to {residual:.2f} px, "
            f"over the tolerance of {tolerance_px:.2f} px"
        )
    pose = np.eye(4)
    pose[:3, :3] = cv2.Rodrigues(rvec)[0]
    pose[:3, 3] = tvec.ravel()
    if pose[2, 3] <= 0:
        raise NotLocated("the only pose that fits puts the object behind the camera")
    return Located(pose, residual, used)
