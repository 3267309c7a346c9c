"""The robot camera while the robot moves: captures through the camera SysRep, outside the procedure.

A procedure captures images where its author wants them (their paths arrive in command
results). Between those, the operator still wants to see the arm move, as RViz would show it.
While an ``execute_plan`` command is in flight, this feed calls the camera SysRep's ``capture``
command every ``period`` seconds and keeps the newest image path. The captures only look: they
change no robot or run state, so they go straight to the gateway rather than through the
executive, and they are not audit records (the procedure's own captures are).
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path

from pride.event_payloads import CommandResult, CommandSent
from pride.events import Event
from pride.systems import SystemGateway

__all__ = ["CameraFeed", "LiveImage", "MOTION_COMMAND"]

log = logging.getLogger(__name__)

#: The SysRep and command whose execution moves the robot.
MOTION_COMMAND = ("affordance_templates", "execute_plan")
CAMERA_SYSREP = "camera"
CAPTURE_COMMAND = "capture"


class LiveImage:
    """One image the feed captured: where it is and when."""

    def __init__(self, path: Path, time_s: float, seq: int) -> None:
        self.path = path
        self.time = time_s
        self.seq = seq


class CameraFeed:
    """Captures while the robot moves; :meth:`event_callback` is an executive listener."""

    def __init__(self, gateway: SystemGateway, camera: str, *, period: float = 0.5, label: str = "web_view") -> None:
        self._gateway = gateway
        self._camera = camera
        self._period = period
        self._label = label
        self._moving = threading.Event()
        self._closed = threading.Event()
        self._lock = threading.Lock()  # guards _latest, _captures
        self._latest: LiveImage | None = None
        self._captures = 0
        self._problem: str | None = None  # the last capture's failure, said once until it changes
        self._thread = threading.Thread(target=self._run, name="camera-feed", daemon=True)
        self._thread.start()

    @staticmethod
    def available(gateway: SystemGateway) -> bool:
        """Whether the gateway serves a camera SysRep to capture with."""
        return CAMERA_SYSREP in gateway.system_ids()

    def event_callback(self, event: Event) -> None:
        """Start capturing when a motion command is sent, stop when its result arrives."""
        data = event.data
        if not isinstance(data, (CommandSent, CommandResult)) or (data.system, data.command) != MOTION_COMMAND:
            return
        if isinstance(data, CommandSent):
            self._moving.set()
        else:
            self._moving.clear()

    def latest(self) -> LiveImage | None:
        with self._lock:
            return self._latest

    def close(self) -> None:
        self._closed.set()
        self._moving.set()  # wake the thread so it sees the close
        self._thread.join(5)

    def _run(self) -> None:
        while not self._closed.is_set():
            self._moving.wait()
            while self._moving.is_set() and not self._closed.is_set():
                self._capture()
                self._closed.wait(self._period)

    def _capture(self) -> None:
        started = time.time()  # an image shows the moment it was asked for, not when it arrived
        try:
            result = self._gateway.execute(
                CAMERA_SYSREP, CAPTURE_COMMAND, {"camera": self._camera, "label": self._label}
            )
        except Exception as exc:
            self._failed(f"camera capture failed: {type(exc).__name__}: {exc}")
            return
        path = result.values.get("path")
        if not result.success or not path:
            self._failed(f"camera capture gave no image: {result.message}")
            return
        if self._problem is not None:
            log.info("camera capture gives images again")
            self._problem = None
        with self._lock:
            self._captures += 1
            self._latest = LiveImage(Path(path), started, self._captures)

    def _failed(self, problem: str) -> None:
        """Warn of a failing capture once, not every period: the same failure repeats while the arm moves."""
        log.log(logging.DEBUG if problem == self._problem else logging.WARNING, "%s", problem)
        self._problem = problem
