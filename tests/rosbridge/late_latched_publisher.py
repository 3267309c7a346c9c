"""A latched (transient-local) publisher that appears after a client subscribed: publishes one
String on the topic given as argument, prints ``READY late``, then spins until stopped."""

from __future__ import annotations

import sys

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.qos import DurabilityPolicy, QoSProfile
from std_msgs.msg import String


def main() -> int:
    rclpy.init()
    node = rclpy.create_node("bridge_test_late_latched")
    publisher = node.create_publisher(
        String, sys.argv[1], QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    )
    publisher.publish(String(data="late latched value"))
    print("READY late", flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
