"""A real rclpy node the bridge tests talk to through the bridge (run as its own process).

Offers: /peer/echo_in -> /peer/echo_out (std_msgs/String echo), /peer/set_bool (SetBool,
echoes data), /peer/slow (Trigger, answers after 2 s while other callbacks go on),
/peer/latched (String, transient local), /peer/follow (caretaker_sim_msgs FollowJointTrajectory:
one feedback per point, 0.2 s apart; goal_tolerance < 0 aborts; cancel honoured), and a
parameter ``greeting``.  Prints ``READY peer`` once everything exists.
"""

from __future__ import annotations

import sys
import threading

import rclpy
from caretaker_sim_msgs.action import FollowJointTrajectory
from rclpy.action import ActionServer, CancelResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger

SLOW_SERVICE_S = 2.0


class PeerNode(Node):
    """Echo topic, services, a latched topic and an action server for the bridge tests."""

    def __init__(self) -> None:
        super().__init__("bridge_test_peer")
        group = ReentrantCallbackGroup()
        deep = QoSProfile(depth=1000)  # many concurrent requests: the default depth 10 drops some
        self.declare_parameter("greeting", "hello")
        self.echo_publisher = self.create_publisher(String, "/peer/echo_out", 1000)
        self.create_subscription(String, "/peer/echo_in", self.echo_callback, 1000)
        self.create_service(SetBool, "/peer/set_bool", self.set_bool_callback, qos_profile=deep, callback_group=group)
        self.create_service(Trigger, "/peer/slow", self.slow_callback, qos_profile=deep, callback_group=group)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.latched_publisher = self.create_publisher(String, "/peer/latched", latched)
        self.latched_publisher.publish(String(data="latched value"))
        self.action_server = ActionServer(
            self,
            FollowJointTrajectory,
            "/peer/follow",
            self.follow_callback,
            cancel_callback=lambda _: CancelResponse.ACCEPT,
            callback_group=group,
        )

    def echo_callback(self, message: String) -> None:
        self.echo_publisher.publish(message)

    def set_bool_callback(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        response.success = request.data
        response.message = f"got {str(request.data).lower()}"
        return response

    def slow_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        threading.Event().wait(SLOW_SERVICE_S)  # simulates a slow server; other callbacks run on other threads
        response.success = True
        response.message = "slow answer"
        return response

    def follow_callback(self, goal_handle: ServerGoalHandle) -> FollowJointTrajectory.Result:
        goal = goal_handle.request
        result = FollowJointTrajectory.Result()
        if goal.goal_tolerance < 0:
            goal_handle.abort()
            result.error_code, result.error_string = -1, "negative tolerance"
            return result
        for index, point in enumerate(goal.trajectory.points):
            if goal_handle.is_cancel_requested:
                goal_handle.canceled()
                result.error_string = "canceled"
                return result
            feedback = FollowJointTrajectory.Feedback(
                joint_names=list(goal.trajectory.joint_names),
                desired=list(point.positions),
                time_from_start=float(index),
            )
            goal_handle.publish_feedback(feedback)
            threading.Event().wait(0.2)  # the robot "moving" between points
        goal_handle.succeed()
        result.error_string = f"followed {len(goal.trajectory.points)} points"
        return result


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    node = PeerNode()
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    print("READY peer", flush=True)
    try:
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
