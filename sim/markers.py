"""Fiducial markers drawn on the simulated objects: a textured square per declared marker.

Each marker is a flat quad (a mesh with texture coordinates, so the image lands on it exactly
as printed) carrying an OpenCV-generated marker image with one white cell of quiet zone around
the black border, as printed tags have: the detector needs it to find the border. The textures
are PNG files in a folder of the simulation's own (pybullet loads textures from files only).
"""

from __future__ import annotations

import tempfile
from pathlib import Path

import cv2
import numpy as np
import pybullet as p

from sim.scene import MarkerSpec

__all__ = ["MarkerTextures", "marker_visual"]

#: Pixels per marker cell in a texture: TinyRenderer samples the nearest texel, so a cell must
#: stay a block of several texels for its edges to stay straight at any viewing angle.
CELL_PX = 16
#: White cells around the black border (the quiet zone).
QUIET_CELLS = 1


def _cells(dictionary: str) -> int:
    """Cells across a marker of ``dictionary``, its black border included."""
    return int(cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary)).markerSize) + 2


def marker_visual(spec: MarkerSpec, dictionary: str, client: int) -> int:
    """A visual-only quad for ``spec`` placed at its pose in its frame, to be textured."""
    cells = _cells(dictionary)
    half = spec.size / 2 * (cells + 2 * QUIET_CELLS) / cells
    return int(
        p.createVisualShape(
            p.GEOM_MESH,
            vertices=[[-half, -half, 0.0], [half, -half, 0.0], [half, half, 0.0], [-half, half, 0.0]],
            indices=[0, 1, 2, 0, 2, 3],
            uvs=[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
            normals=[[0.0, 0.0, 1.0]] * 4,
            visualFramePosition=list(spec.pose.xyz),
            visualFrameOrientation=list(spec.pose.quaternion),
            physicsClientId=client,
        )
    )


class MarkerTextures:
    """Texture ids of printed markers (and of a blank, covered one), made once per id."""

    def __init__(self, dictionary: str, client: int) -> None:
        self._dictionary = cv2.aruco.getPredefinedDictionary(getattr(cv2.aruco, dictionary))
        self._cells = _cells(dictionary)
        self._client = client
        self._folder = Path(tempfile.mkdtemp(prefix="caretaker-markers-"))
        self._ids: dict[int, int] = {}

    def texture(self, printed_id: int) -> int:
        """The texture showing marker ``printed_id``; -1 is a blank (covered) marker."""
        if printed_id not in self._ids:
            side = (self._cells + 2 * QUIET_CELLS) * CELL_PX
            image = np.full((side, side), 255, np.uint8)
            if printed_id >= 0:
                quiet = CELL_PX * QUIET_CELLS
                image[quiet:-quiet, quiet:-quiet] = cv2.aruco.generateImageMarker(
                    self._dictionary, printed_id, self._cells * CELL_PX, borderBits=1
                )
            path = self._folder / f"marker_{printed_id}.png"
            cv2.imwrite(str(path), cv2.cvtColor(image, cv2.COLOR_GRAY2BGR))
            self._ids[printed_id] = int(p.loadTexture(str(path), physicsClientId=self._client))
        return self._ids[printed_id]

    def close(self) -> None:
        for path in self._folder.glob("*.png"):
            path.unlink()
        self._folder.rmdir()
