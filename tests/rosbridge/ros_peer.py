"""A real rclpy node the bridge tests talk to through the bridge (run as its own process).

Offers: /peer/echo_in -> /peer/echo_out (std_msgs/String echo), /peer/set_bool (SetBool,
echoes data), /peer/slow (Trigger, answers after 2 s without blocking its executor),
/peer/latched (String, transient local), /peer/follow (caretaker_sim_msgs FollowJointTrajectory:
one feedback per point, 0.2 s apart; goal_tolerance < 0 aborts; cancel honoured), and a
parameter ``greeting``.  Prints ``READY peer`` once everything exists.
"""

from __future__ import annotations

import sys

import rclpy
from rclpy.action import ActionServer, CancelResponse
from rclpy.executors import ExternalShutdownException, SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile
from rclpy.task import Future

from caretaker_sim_msgs.action import FollowJointTrajectory
from std_msgs.msg import String
from std_srvs.srv import SetBool, Trigger


class PeerNode(Node):
    """Echo topic, services, a latched topic and an action server for the bridge tests."""

    def __init__(self) -> None:
        super().__init__("bridge_test_peer")
        self.declare_parameter("greeting", "hello")
        self.echo_publisher = self.create_publisher(String, "/peer/echo_out", 1000)
        self.create_subscription(String, "/peer/echo_in", self.echo_callback, 1000)
        self.create_service(SetBool, "/peer/set_bool", self.set_bool_callback)
        self.create_service(Trigger, "/peer/slow", self.slow_callback)
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.latched_publisher = self.create_publisher(String, "/peer/latched", latched)
        self.latched_publisher.publish(String(data="latched value"))
        self.action_server = ActionServer(self, FollowJointTrajectory, "/peer/follow", self.follow_callback,
                                          cancel_callback=lambda _: CancelResponse.ACCEPT)

    def echo_callback(self, message: String) -> None:
        self.echo_publisher.publish(message)

    def set_bool_callback(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        response.success = request.data
        response.message = f"got {str(request.data).lower()}"
        return response

    async def slow_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        await self.after(2.0)
        response.success = True
        response.message = "slow answer"
        return response

    async def follow_callback(self, goal_handle) -> FollowJointTrajectory.Result:
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
            feedback = FollowJointTrajectory.Feedback(joint_names=list(goal.trajectory.joint_names),
                                                      desired=list(point.positions), time_from_start=float(index))
            goal_handle.publish_feedback(feedback)
            await self.after(0.2)
        goal_handle.succeed()
        result.error_string = f"followed {len(goal.trajectory.points)} points"
        return result

    def after(self, seconds: float) -> Future:
        """A future done ``seconds`` from now (a one-shot timer; the executor stays free)."""
        future = Future()

        def timer_callback() -> None:
            timer.cancel()
            self.destroy_timer(timer)
            future.set_result(None)

        timer = self.create_timer(seconds, timer_callback)
        return future


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    node = PeerNode()
    executor = SingleThreadedExecutor()
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
