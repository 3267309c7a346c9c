"""The latest world poses of named frames, as the simulation (or perception) publishes them.

The original server resolved frames through TF and waited up to 3 s for them; here the
simulation's ``/sim/frames`` is the ground truth and ``world`` is the identity.
"""

from __future__ import annotations

import threading
import time

import numpy as np

__all__ = ["FrameTable", "UnknownFrame", "WORLD_FRAME"]

WORLD_FRAME = "world"


class UnknownFrame(KeyError):
    """A frame name nobody publishes; the message lists some that exist."""

    def __str__(self) -> str:
        return str(self.args[0])


class FrameTable:
    def __init__(self) -> None:
        self._poses: dict[str, np.ndarray] = {}
        self._stamp = 0.0
        # Guards _poses and _stamp (subscription vs service threads); notified on every update.
        self._lock = threading.Condition()

    def update(self, names: list[str], poses: list[np.ndarray]) -> None:
        with self._lock:
            self._poses = dict(zip(names, poses, strict=False))
            self._stamp = time.monotonic()
            self._lock.notify_all()

    @property
    def age(self) -> float:
        """Seconds since the last update (infinite before the first one)."""
        with self._lock:
            return time.monotonic() - self._stamp if self._stamp else float("inf")

    def snapshot(self) -> dict[str, np.ndarray]:
        with self._lock:
            out = dict(self._poses)
        out[WORLD_FRAME] = np.eye(4)
        return out

    def lookup(self, name: str, timeout: float = 0.0) -> np.ndarray:
        """World pose of frame ``name``, waiting up to ``timeout`` s for it to be published
        (the original server waited up to 3 s for TF).

        Raises:
            UnknownFrame: nobody publishes ``name`` (or nothing was received yet).
        """
        if name in ("", WORLD_FRAME):
            return np.eye(4)
        with self._lock:
            self._lock.wait_for(lambda: name in self._poses, timeout)
            pose = self._poses.get(name)
            known = sorted(self._poses)
        if pose is None:
            if not known:
                raise UnknownFrame(f"unknown frame {name!r}: no frames received on /sim/frames yet")
            raise UnknownFrame(f"unknown frame {name!r}; known frames: {WORLD_FRAME}, {', '.join(known)}")
        return pose.copy()
