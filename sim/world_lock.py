"""The lock that every thread touching the pybullet world holds, fair to the ROS callbacks.

The stepping thread takes the lock again right after each step. With a plain lock it almost
always wins: a waiting thread woken by the release comes too late, because the stepper is
already holding the lock again. On a quiet machine the stepper sleeps between steps and that
leaves room; on a loaded one it falls behind real time, stops sleeping, and a trajectory goal,
a halt or a camera capture could wait seconds for the world (a goal accepted by the controller
once started about 45 s late). Here the stepper, before taking the lock again, lets every thread
that is waiting for it have it first.
"""

from __future__ import annotations

import threading
from types import TracebackType

__all__ = ["WorldLock"]

#: The longest the stepper lets others go first (s): the physics must not stall behind a thread
#: that is waiting for something else.
GIVE_WAY_LIMIT_S = 1.0


class WorldLock:
    """A re-entrant lock (``with lock:``) with :meth:`give_way` for the thread that steps the world."""

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self._waiters = threading.Condition(threading.Lock())
        self._waiting = 0  # threads in acquire() that do not hold the lock yet

    def __enter__(self) -> WorldLock:
        with self._waiters:
            self._waiting += 1
        try:
            self._lock.acquire()
        finally:
            with self._waiters:
                self._waiting -= 1
                if self._waiting == 0:
                    self._waiters.notify_all()
        return self

    def __exit__(
        self, kind: type[BaseException] | None, error: BaseException | None, trace: TracebackType | None
    ) -> None:
        self._lock.release()

    def give_way(self) -> None:
        """Return once every thread waiting for the lock has had it (call without holding it)."""
        with self._waiters:
            self._waiters.wait_for(lambda: self._waiting == 0, GIVE_WAY_LIMIT_S)
