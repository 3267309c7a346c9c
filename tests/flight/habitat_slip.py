"""The gripper's fault, struck from inside the habitat: the held filter slips out while the arm pulls it.

Runs in the habitat's network namespace next to ``caretaker up``: ``habitat_slip.py TRAJECTORY
--pace SCALE --then SCALE``. When the AT server starts executing ``TRAJECTORY`` (its status topic)
it paces the simulation at ``--pace`` (its ``time_scale`` parameter, :mod:`support.sim_pace`), so
that the motion lasts long enough for the habitat's executive to halt it; once the gripper holds
(``gripper/grasp``) and the arm's joints move away from where they were when it closed, it calls
the simulation's ``sim/check/slip`` (a service for tests only) once and prints ``SLIPPED <time>
<message>`` (``time``: this host's clock when the answer came, Unix seconds) or ``NOT SLIPPED
<message>``; when that execution ends it paces the simulation at ``--then`` again (``PACE`` lines
say each change). The fault is struck from here because a call from the ground lands 1.3 s after
what it saw: too late for a motion.

Prints ``READY slip`` once its subscriptions exist and both services answer.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import rclpy
from affordance_template_msgs.msg import ServerStatus
from habitat_probe import MOVED_RAD
from rcl_interfaces.srv import SetParameters
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from sensor_msgs.msg import JointState
from std_msgs.msg import String
from std_srvs.srv import Trigger

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # tests/, for the support package
from support.sim_pace import SIM_PARAMETERS, time_scale_request


class HabitatSlip(Node):
    def __init__(self, trajectory: str, pace: float, then: float) -> None:
        super().__init__("flight_habitat_slip")
        self.trajectory, self.pace, self.then = trajectory, pace, then
        self.executing = False
        self.closed_at: tuple[float, ...] | None = None  # the joints when the gripper closed on the filter
        self.positions: tuple[float, ...] = ()
        self.asked = False
        self.slip = self.create_client(Trigger, "/sim/check/slip")
        self.parameters = self.create_client(SetParameters, SIM_PARAMETERS)
        latched = QoSProfile(
            depth=1, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL
        )
        self.create_subscription(ServerStatus, "/affordance_template_server/status", self.on_status, 10)
        self.create_subscription(String, "/gripper/grasp", self.on_grasp, latched)
        self.create_subscription(JointState, "/joint_states", self.on_joints, 100)

    def on_status(self, status: ServerStatus) -> None:
        executing = (
            status.execute_status == ServerStatus.EXECUTE_EXECUTING and status.active_trajectory == self.trajectory
        )
        if executing != self.executing and (executing or self.asked):  # its start, or its end after the slip
            self.set_pace(self.pace if executing else self.then)
        self.executing = executing

    def set_pace(self, scale: float) -> None:
        def said(future: Future) -> None:
            result = future.result()
            assert isinstance(result, SetParameters.Response)
            print(f"PACE {scale:g} {'set' if result.results[0].successful else 'refused'}", flush=True)

        self.parameters.call_async(time_scale_request(scale)).add_done_callback(said)

    def on_grasp(self, message: String) -> None:
        self.closed_at = self.positions if message.data == "holding" else None

    def on_joints(self, message: JointState) -> None:
        self.positions = tuple(message.position)
        if self.asked or not self.executing or not self.closed_at:
            return
        if max(abs(a - b) for a, b in zip(self.positions, self.closed_at, strict=False)) > MOVED_RAD:
            self.asked = True  # once: the pull is under way with the filter in the gripper
            self.slip.call_async(Trigger.Request()).add_done_callback(self.answered)

    def answered(self, future: Future) -> None:
        answer = future.result()
        assert isinstance(answer, Trigger.Response)
        if answer.success:
            print(f"SLIPPED {time.time():.6f} {answer.message}", flush=True)
        else:
            print(f"NOT SLIPPED {answer.message}", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("trajectory", help="the execution during which the held filter slips out")
    parser.add_argument("--pace", type=float, required=True, help="the simulation's time scale during it")
    parser.add_argument("--then", type=float, required=True, help="the simulation's time scale after it")
    args = parser.parse_args()
    rclpy.init()
    node = HabitatSlip(args.trajectory, args.pace, args.then)
    for client in (node.slip, node.parameters):
        if not client.wait_for_service(timeout_sec=60):
            raise SystemExit(f"{client.srv_name} is not served in the habitat")
    print("READY slip", flush=True)
    try:
        rclpy.spin(node)
    except KeyboardInterrupt:
        pass
    finally:
        node.destroy_node()  # type: ignore[no-untyped-call]  # rclpy leaves it unannotated
        rclpy.try_shutdown()


if __name__ == "__main__":
    main()
