"""A run's control of its robot: taken when the run starts, checked before each command, given up at the end.

Where control is recorded is a :class:`ControlStore`: on the ground, the ground database
(:class:`records.robot_control.RobotControl`). It is kept apart from that store so the executive
imports no database library (an onboard executive has none).
"""

from __future__ import annotations

import logging
from typing import Protocol

from pride.states import Controller, OperatorActionError, RefusalRule

__all__ = ["ControlStore", "RobotControlled", "RunControl"]

log = logging.getLogger(__name__)


class RobotControlled(OperatorActionError):
    """The robot is controlled by another run: ``holder`` says which, by whom, since when."""

    def __init__(self, holder: Controller) -> None:
        super().__init__(
            f"robot {holder.robot} is controlled by {holder.describe()}: take over with a reason "
            "to control it from this run",
            rule=RefusalRule.ONE_RUN_PER_ROBOT,
        )
        self.holder = holder


class ControlStore(Protocol):
    """Where control of robots is recorded, shared by every run that may command them.

    Each change is atomic: two runs can never both hold a robot.
    """

    def holder(self, robot: str) -> Controller | None:
        """Who controls ``robot`` now (None: nobody)."""

    def acquire(self, robot: str, run_id: str, user: str) -> Controller:
        """Take control of ``robot`` for ``run_id``, or raise :class:`RobotControlled` naming the holder."""

    def take_over(self, robot: str, run_id: str, user: str, reason: str) -> Controller | None:
        """Control of ``robot`` for ``run_id`` whoever held it; the previous holder (None: nobody)."""

    def release(self, robot: str, run_id: str) -> None:
        """Give ``robot`` up if ``run_id`` still holds it."""


class RunControl:
    """One run's side of robot control: take the robot, check it before each command, give it up.

    Without a :class:`ControlStore` (a bench with one run) every check passes and nothing is stored.
    """

    def __init__(self, control: ControlStore | None, robot: str, run_id: str) -> None:
        self.control = control
        self.robot = robot
        self.run_id = run_id
        self.held = False  # taken by this run (it may have been taken over since)

    def take(self, user: str, take_over: str | None) -> Controller | None:
        """Acquire the robot, or take it over with a reason; the previous holder when taken from another run.

        Raises:
            RobotControlled: another run holds it and ``take_over`` is None.
        """
        if self.control is None:
            return None
        if take_over is None:
            self.control.acquire(self.robot, self.run_id, user)
            self.held = True
            return None
        previous = self.control.take_over(self.robot, self.run_id, user, take_over)
        self.held = True
        return previous if previous is not None and previous.run_id != self.run_id else None

    def lost(self) -> tuple[bool, Controller | None]:
        """(whether another run controls the robot now, who): asked in the database, not remembered."""
        if self.control is None:
            return False, None
        holder = self.control.holder(self.robot)
        return holder is None or holder.run_id != self.run_id, holder

    def lost_text(self, holder: Controller | None) -> str:
        if holder is None:
            return f"control of robot {self.robot} was taken by another run (and released): take control again"
        return f"control taken over by {holder.user} (run {holder.run_id}): {holder.reason or 'no reason given'}"

    def release(self) -> None:
        """Give the robot up (a no-op when another run took it)."""
        if self.control is None:
            return
        try:
            self.control.release(self.robot, self.run_id)
        except Exception:  # the run is over either way; the row names it until someone takes over
            log.exception("run %s: releasing robot %s failed", self.run_id, self.robot)
