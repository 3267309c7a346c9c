"""Watch the habitat from inside it: what the arm really did, whatever the ground believes.

Runs in the habitat's network namespace next to ``caretaker up`` and prints one line per fact:

- ``EXECUTING <template> <trajectory>`` when the AT server starts executing (its status topic),
  ``EXECUTED <template> <trajectory> <status>`` when it stops;
- ``GOAL <id> <status>`` when a trajectory goal of the arm's controller ends (4 succeeded,
  5 canceled, 6 aborted), once per goal: every arm motion the simulation carried out;
- ``MOVING <time>`` and ``STILL <time>`` when the arm's joint states start to change (by more than
  :data:`MOVED_RAD` from where it came to rest) and stop changing (``time``: this host's clock when
  the first such sample arrived, Unix seconds).

With ``--pace TRAJECTORY=SCALE`` (repeatable) and ``--then SCALE`` it paces the simulation (its
``time_scale`` parameter, :mod:`support.sim_pace`) at ``SCALE`` while the AT server executes
``TRAJECTORY``, and at ``--then`` once that execution ends (a ``PACE <scale> set`` line each time;
refused, the probe exits saying why): a flight flat out but for the motion its fault must fall
in. The ``EXECUTING`` line of a paced execution comes once its pace is set, so a test that acts
on that line acts on a motion already paced.

Prints ``READY probe`` once both subscriptions exist.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import rclpy
from action_msgs.msg import GoalStatusArray
from affordance_template_msgs.msg import ServerStatus
from rcl_interfaces.srv import SetParameters
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from sensor_msgs.msg import JointState

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/, for the support package
from support.sim_pace import SIM_PARAMETERS, time_scale_request

TERMINAL = {4, 5, 6}
#: How far a joint must get from where the arm came to rest for it to be moving again: a goal that
#: starts moves it by hundredths of a radian within a round trip; the physics' last settling
#: after a halt changes the published values by far less than this, and is no motion.
MOVED_RAD = 1e-4


class HabitatProbe(Node):
    def __init__(
        self, status_topic: str, action: str, joints_topic: str, paces: dict[str, float], then: float | None
    ) -> None:
        super().__init__("flight_habitat_probe")
        self.paces, self.then = paces, then
        self.parameters = self.create_client(SetParameters, SIM_PARAMETERS)
        self.executing: tuple[str, str] | None = None
        self.ended: set[str] = set()
        self.positions: tuple[float, ...] | None = None
        self.rest: tuple[float, ...] = ()  # where the arm last came to rest
        self.moving = False
        self.create_subscription(JointState, joints_topic, self.on_joints, 100)
        self.create_subscription(ServerStatus, status_topic, self.on_status, 10)
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        self.create_subscription(GoalStatusArray, f"{action}/_action/status", self.on_goals, latched)

    def on_status(self, status: ServerStatus) -> None:
        if status.execute_status == ServerStatus.EXECUTE_EXECUTING and self.executing is None:
            self.executing = (status.active_template, status.active_trajectory)
            said = f"EXECUTING {self.executing[0]} {self.executing[1]}"
            if status.active_trajectory in self.paces:
                self.set_pace(self.paces[status.active_trajectory], then_print=said)
            else:
                print(said, flush=True)
        elif status.execute_status != ServerStatus.EXECUTE_EXECUTING and self.executing is not None:
            print(f"EXECUTED {self.executing[0]} {self.executing[1]} {status.execute_status}", flush=True)
            if self.executing[1] in self.paces and self.then is not None:
                self.set_pace(self.then)
            self.executing = None

    def set_pace(self, scale: float, *, then_print: str = "") -> None:
        """Pace the simulation at ``scale``; once it is, print ``then_print`` too."""

        def said(future: Future) -> None:
            result = future.result()
            assert isinstance(result, SetParameters.Response)
            if not result.results[0].successful:
                raise SystemExit(f"PACE {scale:g} refused: {result.results[0].reason}")
            print(f"PACE {scale:g} set", flush=True)
            if then_print:
                print(then_print, flush=True)

        self.parameters.call_async(time_scale_request(scale)).add_done_callback(said)

    def on_joints(self, message: JointState) -> None:
        positions = tuple(message.position)
        if self.positions is None:
            self.rest = positions
        elif self.moving and positions == self.positions:
            self.moving = False
            self.rest = positions
            print(f"STILL {time.time():.6f}", flush=True)
        elif not self.moving and max(abs(a - b) for a, b in zip(positions, self.rest, strict=False)) > MOVED_RAD:
            self.moving = True
            print(f"MOVING {time.time():.6f}", flush=True)
        self.positions = positions

    def on_goals(self, message: GoalStatusArray) -> None:
        for goal in message.status_list:
            goal_id = bytes(goal.goal_info.goal_id.uuid).hex()
            if goal.status in TERMINAL and goal_id not in self.ended:
                self.ended.add(goal_id)
                print(f"GOAL {goal_id} {goal.status}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--status-topic", default="/affordance_template_server/status")
    parser.add_argument("--action", default="/arm_controller/follow_joint_trajectory")
    parser.add_argument("--joints", default="/joint_states")
    parser.add_argument(
        "--pace", action="append", default=[], metavar="TRAJECTORY=SCALE", help="the time scale while it executes"
    )
    parser.add_argument("--then", type=float, help="the time scale once a paced execution ends")
    args = parser.parse_args()
    paces = {trajectory: float(scale) for trajectory, _, scale in (pace.partition("=") for pace in args.pace)}
    rclpy.init()
    node = HabitatProbe(args.status_topic, args.action, args.joints, paces, args.then)
    print("READY probe", flush=True)
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()  # type: ignore[no-untyped-call]  # rclpy leaves it unannotated
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
