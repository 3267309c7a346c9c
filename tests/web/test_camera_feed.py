"""The live camera feed's log: a capture that keeps failing while the arm moves is said once, not every period."""

from __future__ import annotations

import logging
import threading
from pathlib import Path
from typing import Any

import pytest

from console.camera_feed import CameraFeed
from pride.events import Event, EventKind
from pride.systems import CommandResult, Outcome


class Camera:
    """A camera SysRep that answers each capture with the next of ``answers`` (the last one repeats)."""

    def __init__(self, answers: list[CommandResult]) -> None:
        self._answers = answers
        self.captures = 0
        self.enough = threading.Event()

    def execute(self, sysrep_id: str, command_id: str, args: Any, *, key: str | None = None) -> CommandResult:
        answer = self._answers[min(self.captures, len(self._answers) - 1)]
        self.captures += 1
        if self.captures >= 2 * len(self._answers):
            self.enough.set()
        return answer


def _moving(feed: CameraFeed, kind: EventKind) -> None:
    feed.event_callback(
        Event("run", 1, kind, "PAX", "1.1", {"system": "affordance_templates", "command": "execute_plan"})
    )


@pytest.mark.parametrize("recovers", [False, True])
def test_a_failing_capture_is_warned_of_once_and_its_recovery_is_said(
    caplog: pytest.LogCaptureFixture, tmp_path: Path, recovers: bool
) -> None:
    unknown = CommandResult(Outcome.FAILED, "unknown camera 'ee_camera'; cameras are ['scene']")
    image = CommandResult(Outcome.SUCCEEDED, "", {"path": str(tmp_path / "view.png")})
    camera = Camera([unknown, unknown, unknown, *([image] if recovers else [])])
    caplog.set_level(logging.DEBUG, logger="console.camera_feed")
    feed = CameraFeed(camera, "ee_camera", period=0.001)  # type: ignore[arg-type]
    try:
        _moving(feed, EventKind.COMMAND_SENT)
        assert camera.enough.wait(10), f"only {camera.captures} captures"
        _moving(feed, EventKind.COMMAND_RESULT)
    finally:
        feed.close()
    warnings = [r.getMessage() for r in caplog.records if r.levelno == logging.WARNING]
    assert warnings == ["camera capture gave no image: unknown camera 'ee_camera'; cameras are ['scene']"]
    assert ("camera capture gives images again" in caplog.messages) is recovers
    assert (feed.latest() is not None) is recovers
