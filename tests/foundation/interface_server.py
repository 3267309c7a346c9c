"""A minimal AddAffordanceTemplate server in its own process, for the interface round-trip test."""

from __future__ import annotations

import sys

import rclpy
from affordance_template_msgs.srv import AddAffordanceTemplate
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node


class EchoServer(Node):
    def __init__(self) -> None:
        super().__init__("interface_echo_server")
        self.srv = self.create_service(
            AddAffordanceTemplate, "/affordance_template_server/add_template", self.add_callback
        )

    def add_callback(
        self, request: AddAffordanceTemplate.Request, response: AddAffordanceTemplate.Response
    ) -> AddAffordanceTemplate.Response:
        response.success = request.class_type == "cdra_filter"
        response.id = 7
        response.instance = f"{request.class_type}:7"
        response.message = f"frame {request.pose.header.frame_id} hide={request.hide_waypoints}"
        return response


def main() -> None:
    rclpy.init()
    node = EchoServer()
    print("READY interface_server", flush=True)
    try:
        rclpy.spin(node)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    sys.exit(main())
