"""How much of the simulator's time its camera images may take.

Rendering holds the world lock, and pybullet keeps Python's GIL while it draws: every frame is
time in which the physics does not step. On a quiet machine a frame takes milliseconds; on a
starved one it took up to a second, and with the console's camera feed asking twice a second
during a motion, an arm trajectory stood still (0.12 s of a 1.79 s trajectory done in 35 s,
until the AT server gave up on it). So frames get at most :attr:`RenderBudget.duty` of the
time: after a frame that took T, the next one waits until T × (1/duty − 1) has passed. The
camera stream thins out on a loaded machine; the physics does not.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

__all__ = ["RenderBudget"]


class RenderBudget:
    """Turns to render, one at a time, spaced so that rendering takes at most ``duty`` of the time."""

    def __init__(self, duty: float = 0.25, clock: Callable[[], float] = time.monotonic) -> None:
        if not 0 < duty <= 1:
            raise ValueError(f"duty must be in (0, 1], got {duty}")
        self.duty = duty
        self._clock = clock
        self._turn = threading.Condition()
        self._rendering = False
        self._next = float("-inf")  # when the next frame may start

    def take_turn(self, wait: bool) -> bool:
        """Start a frame now if it is due (return True; call :meth:`done` after it). Without
        ``wait``, return False at once when it is not due (a periodic image is skipped); with
        it, wait for the turn (a requested capture is delayed, never refused)."""
        with self._turn:
            while True:
                now = self._clock()
                if not self._rendering and now >= self._next:
                    self._rendering = True
                    return True
                if not wait:
                    return False
                self._turn.wait(None if self._rendering else self._next - now)

    def done(self, seconds: float) -> None:
        """The frame begun by :meth:`take_turn` took ``seconds``; the next waits accordingly."""
        with self._turn:
            self._rendering = False
            self._next = self._clock() + seconds * (1 / self.duty - 1)
            self._turn.notify_all()
