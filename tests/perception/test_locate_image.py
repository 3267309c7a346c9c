"""perception.locate on images drawn here with OpenCV: the geometry without a simulator, and the
refusals that a rendered world rarely produces (a marker cut by the image edge, one id twice)."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from perception_client import errors

from at_ros.transforms import from_xyz_rpy
from perception.locate import Calibration, MarkerOnObject, NotLocated, locate

pytestmark = pytest.mark.slow(seconds=3)

DICTIONARY = "DICT_APRILTAG_36h11"
CALIBRATION = Calibration(640, 480, np.array([[580.0, 0.0, 320.0], [0.0, 580.0, 240.0], [0.0, 0.0, 1.0]]))
#: Two 10 cm markers 30 cm apart on the object's x axis, facing along its z.
MARKERS = [
    MarkerOnObject(7, 0.10, from_xyz_rpy((0.15, 0.0, 0.0), (0.0, 0.0, 0.0))),
    MarkerOnObject(8, 0.10, from_xyz_rpy((-0.15, 0.0, 0.0), (0.0, 0.0, 0.0))),
]


def draw(camera_to_object: np.ndarray, printed: dict[int, int] | None = None) -> np.ndarray:
    """A grey 640x480 image of the object's markers seen from the camera, each printed with the
    id ``printed`` gives it (default its own), with a white margin of one cell."""
    image = np.full((480, 640), 128, np.uint8)
    dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, DICTIONARY))
    for marker in MARKERS:
        side = 100  # px of the printed square in the drawing: 8 cells of the tag and a cell each side
        tag = np.full((side, side), 255, np.uint8)
        tag[10:90, 10:90] = cv2.aruco.generateImageMarker(dictionary, (printed or {}).get(marker.id, marker.id), 80)
        h = marker.size / 2 * 100 / 80  # the margin's half width in m
        corners = np.array([[-h, h, 0, 1], [h, h, 0, 1], [h, -h, 0, 1], [-h, -h, 0, 1]], dtype=float)
        in_camera = (camera_to_object @ marker.pose @ corners.T).T[:, :3]
        pixels = (CALIBRATION.matrix @ in_camera.T).T
        pixels = (pixels[:, :2] / pixels[:, 2:]).astype(np.float32)
        source = np.array([[0, 0], [side, 0], [side, side], [0, side]], dtype=np.float32)
        warp = cv2.getPerspectiveTransform(source, pixels)
        drawn = cv2.warpPerspective(tag, warp, (640, 480), flags=cv2.INTER_AREA, borderValue=0)
        mask = cv2.warpPerspective(np.full_like(tag, 255), warp, (640, 480), borderValue=0)
        image[mask > 0] = drawn[mask > 0]
    return image


def test_a_pose_is_recovered_from_a_drawn_image() -> None:
    truth = from_xyz_rpy((0.03, -0.02, 0.8), (np.radians(170.0), np.radians(12.0), np.radians(4.0)))
    found = locate(draw(truth), CALIBRATION, DICTIONARY, MARKERS, 0.6)
    mm, deg = errors(found.camera_to_object, truth)
    assert found.markers == (7, 8) and mm < 3.0 and deg < 0.5, (mm, deg, found.residual_px)


@pytest.mark.parametrize(
    ("x", "reason"),
    [
        (0.228, None),  # marker 7's right edge 8.7 px inside the image: located
        (0.236, "marker 7 is cut by the image edge"),  # its edge on the last pixels
        (0.241, "marker 7 is cut by the image edge"),  # its border runs off: detected 5 px inside
        (0.238, r"only marker\(s\) 8 of 7, 8 are seen"),  # cut so that it is not detected at all
    ],
)
def test_a_marker_partly_out_of_view_is_refused(x: float, reason: str | None) -> None:
    """Moving the object right until marker 7 runs off the image's right edge (x = 320 px + 580 px
    * (x + 0.2 m) / 0.8 m for its black border)."""
    image = draw(from_xyz_rpy((x, 0.0, 0.8), (np.radians(180.0), 0.0, 0.0)))
    if reason is None:
        assert locate(image, CALIBRATION, DICTIONARY, MARKERS, 0.6).markers == (7, 8)
    else:
        with pytest.raises(NotLocated, match=reason):
            locate(image, CALIBRATION, DICTIONARY, MARKERS, 0.6)


def test_an_id_seen_twice_is_refused() -> None:
    truth = from_xyz_rpy((0.0, 0.0, 0.8), (np.radians(180.0), 0.0, 0.0))
    with pytest.raises(NotLocated, match="marker 7 is seen twice"):
        locate(draw(truth, printed={8: 7}), CALIBRATION, DICTIONARY, MARKERS, 0.6)


def test_an_empty_image_and_an_object_without_markers_are_refused() -> None:
    with pytest.raises(NotLocated, match=r"none of its markers \(7, 8\) is seen; other markers in view: none"):
        locate(np.full((480, 640), 128, np.uint8), CALIBRATION, DICTIONARY, MARKERS, 0.6)
    with pytest.raises(NotLocated, match="no markers are declared on it"):
        locate(np.full((480, 640), 128, np.uint8), CALIBRATION, DICTIONARY, [], 0.6)
