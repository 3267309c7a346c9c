"""Print the ROS graph one rclpy node sees from its namespace, as ``GRAPH {json}``, then exit.

``--wait-for NODE`` returns as soon as NODE is seen (or after ``--seconds``); without it the
probe watches the graph for ``--seconds`` (an absence can only be observed over a window).
"""

from __future__ import annotations

import argparse
import json
import time

import rclpy
from rclpy.node import Node


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--name", required=True)
    parser.add_argument("--wait-for")
    parser.add_argument("--seconds", type=float, required=True)
    args = parser.parse_args()
    rclpy.init()
    node = Node(args.name)
    deadline = time.monotonic() + args.seconds
    nodes: list[str] = []
    while time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=0.2)
        nodes = sorted(f"{namespace.rstrip('/')}/{name}" for name, namespace in node.get_node_names_and_namespaces())
        if args.wait_for and args.wait_for in nodes:
            break
    topics = sorted(name for name, _ in node.get_topic_names_and_types())
    services = sorted(name for name, _ in node.get_service_names_and_types())
    print("GRAPH " + json.dumps({"nodes": nodes, "topics": topics, "services": services}), flush=True)
    node.destroy_node()  # type: ignore[no-untyped-call]  # rclpy 7.1 leaves it unannotated
    rclpy.shutdown()


if __name__ == "__main__":
    main()
