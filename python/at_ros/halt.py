"""Halt: stop the robot's motion at once, whatever it is doing (issue 16).

``affordance_template_server/halt`` (affordance_template_msgs/srv/Halt) is one path to the
stop: it calls the robot's own halt service (``halt_service`` of the robot config; the
simulation's ``robot/halt``), which stops the arm and the gripper before its next physics step,
and it cancels the trajectory goal in flight. The robot-level service is the same stop a
ground that cannot reach the AT server calls directly, so both paths end in one mechanism, and
it stops what a goal cancel cannot (a gripper motion, a goal someone else sent). The goal
cancel is kept as the stop for a robot without a halt service.

The execution in flight learns of a halt through a count: every command notes the halts that
arrived before it was issued (:meth:`HaltSwitch.mark`) and checks the count before each motion it
commands, so a halt while it plans, between waypoints or during a gripper motion ends it too.
"Issued" is when the command reached the robot side (:mod:`ros_process.command_order`: the
command ledger stamps it), not when it reached this server: a halt that overtook a command held
up in the ledger keeps it from moving. Every trajectory goal and gripper request carries that
stamp too, and the robot refuses one issued before a halt it has seen, so a motion request that
crosses the robot's halt on its way never starts either. A trajectory goal is
sent under the switch's lock (:meth:`HaltSwitch.send_goal`), so a halt either comes first (the
goal is not sent) or after; after, it waits for the controller to answer the goal before it
halts the robot, because the controller notes its halts when a goal arrives: a goal that
arrived before the robot's halt never starts after it, whatever order the two requests' threads
take there. (Halting the robot at once and cancelling the goal once accepted let the arm move
for 30 ms under load.) The halt itself never waits for planning or for the execution to wind
down: it answers once the robot confirms it holds still.
"""

from __future__ import annotations

import logging
import threading
from dataclasses import dataclass
from typing import Any

from affordance_template_msgs.srv import Halt
from caretaker_sim_msgs.srv import Halt as RobotHalt

from at_ros.server_core import CommandRefused, ServerCore
from ros_process.command_order import arrived_now, issued_at, stamp

__all__ = ["GOAL_ANSWER_WAIT_S", "HALT_TIMEOUT", "HaltSwitch", "Halted", "Mark"]

LOG = logging.getLogger(__name__)

#: s to wait for the robot to confirm a halt; it answers within a physics step when it can.
HALT_TIMEOUT = 2.0
#: s a halt waits for the controller to answer a goal sent just before it (a local round trip);
#: past it the robot is halted anyway and the goal cancelled once accepted.
GOAL_ANSWER_WAIT_S = 1.0


class Halted(CommandRefused):
    """A command ended by a halt; ``reason`` is the halt's."""

    def __init__(self, reason: str, message: str) -> None:
        super().__init__(message)
        self.reason = reason


@dataclass(frozen=True)
class Mark:
    """A command against the halts: how many had arrived when it was issued, and when that was
    (s of the robot side's clock), which its motion requests carry to the robot."""

    halts: int
    issued: float


class HaltSwitch:
    """The halts so far, and the trajectory goal in flight a halt must cancel.

    ``halt_client`` calls the robot's halt service (caretaker_sim_msgs/srv/Halt), or is None
    for a robot without one.
    """

    def __init__(self, core: ServerCore, *, halt_client: Any | None) -> None:
        self.core = core
        self.halt_client = halt_client
        self._lock = threading.Lock()
        self._count = 0
        self._arrivals: list[float] = []  # when each halt arrived, in order
        self._reason = ""
        self._goal: Any = None  # ClientGoalHandle of the trajectory goal in flight
        self._sending: Any = None  # the future of a goal sent and not yet answered

    def mark(self, issued: Any = None) -> Mark:
        """What a command notes when it starts: the halts that arrived before it was issued.

        ``issued`` is its request's stamp (builtin_interfaces/Time); None or zero: issued now.
        """
        now = arrived_now()
        at = now if issued is None else issued_at(issued, now)
        with self._lock:
            if at >= now:  # issued now (no stamp, or one from another host's future): after every halt so far
                return Mark(self._count, now)
            return Mark(sum(1 for arrived in self._arrivals if arrived < at), at)

    def halted_since(self, mark: Mark) -> str | None:
        """The reason of the last halt if one came after ``mark``, else None."""
        with self._lock:
            return self._reason if self._count != mark.halts else None

    def check(self, mark: Mark, what: str) -> None:
        """Raise :class:`Halted` if a halt came after ``mark``; ``what`` is what it stopped."""
        reason = self.halted_since(mark)
        if reason is not None:
            raise Halted(reason, f"halted ({reason}) {what}")

    def send_goal(self, client: Any, goal: Any, mark: Mark, what: str) -> Any:
        """Send trajectory ``goal`` through action ``client`` unless a halt came after ``mark``
        (:class:`Halted`, ``what`` naming the motion); the future of the goal's answer."""
        with self._lock:
            if self._count != mark.halts:
                raise Halted(self._reason, f"halted ({self._reason}) {what}")
            self._sending = client.send_goal_async(goal)
            return self._sending

    def goal_started(self, handle: Any, mark: Mark) -> None:
        """Note the goal in flight; one accepted after a halt that did not wait for it is cancelled now."""
        with self._lock:
            self._sending = None
            self._goal = handle
            late = self._count != mark.halts
        if late:
            handle.cancel_goal_async()

    def goal_ended(self) -> None:
        """The goal sent is over (ended, refused, or never answered)."""
        with self._lock:
            self._goal = self._sending = None

    def halt(self, request: Halt.Request, response: Halt.Response) -> Any:
        """The halt service: stop everything now, then say what was stopped."""
        core = self.core
        arrived = arrived_now()
        reason = request.reason.strip() or "no reason given"
        with self._lock:
            self._count += 1
            self._arrivals.append(arrived)
            self._reason = reason
            goal = self._goal
            sending = self._sending
        if sending is not None:  # the robot's halt after the controller has this goal: it then never starts
            answered = threading.Event()
            sending.add_done_callback(lambda _: answered.set())
            if answered.wait(GOAL_ANSWER_WAIT_S) and sending.exception() is None and sending.result().accepted:
                goal = sending.result()
        with core.state_lock:
            executing = core.state.executing
            if core.inputs.joints_stamp is not None:
                response.robot_time = core.inputs.joints_stamp
        LOG.warning("halt (%s): %s", reason, f"executing {executing}" if executing else "no execution in flight")
        if goal is not None:
            goal.cancel_goal_async()  # its result tells the execution; nothing to wait for here
        if self.halt_client is not None:
            confirmed, stopped, said = self._halt_robot(self.halt_client, reason, arrived)
        elif goal is not None:
            confirmed, stopped, said = (
                True,
                True,
                "cancelled the trajectory goal (no halt service: a gripper motion goes on)",
            )
        else:
            with core.state_lock:
                moving = core.inputs.moving
            confirmed, stopped = not moving, False
            said = (
                "the robot moves, not by this server's command, and has no halt service (halt_service in its config)"
                if moving
                else ""
            )
        response.halted = executing
        response.success = confirmed
        if executing or stopped:
            response.message = f"halted {executing or 'the robot'} ({reason}): {said}"
        else:
            response.message = "nothing was moving" if confirmed else f"not confirmed: {said}"
        if not confirmed:
            LOG.error("halt not confirmed: %s", said)
        return response

    @staticmethod
    def _halt_robot(client: Any, reason: str, arrived: float) -> tuple[bool, bool, str]:
        """(confirmed, something stopped, what the robot said) of the robot's halt service, told
        that the halt ``arrived`` then: what was issued before it never starts."""
        if not client.wait_for_service(timeout_sec=0.5):
            return False, False, f"the robot's halt service {client.srv_name} is not available"
        request = RobotHalt.Request()
        request.reason = reason
        request.arrived = stamp(arrived)
        done = threading.Event()
        future = client.call_async(request)
        future.add_done_callback(lambda _: done.set())
        if not done.wait(HALT_TIMEOUT):
            future.cancel()
            return (
                False,
                False,
                f"the robot's halt service {client.srv_name} did not answer within {HALT_TIMEOUT:.0f} s",
            )
        if future.exception() is not None:
            return False, False, f"the robot's halt service failed: {future.exception()}"
        result = future.result()
        return bool(result.success), bool(result.stopped), result.message
