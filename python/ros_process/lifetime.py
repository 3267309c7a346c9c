"""The lifetime of a robot-side process's nodes after ``rclpy.init``."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import rclpy
from rclpy.executors import Executor, ExternalShutdownException
from rclpy.impl.implementation_singleton import rclpy_implementation as _rclpy
from rclpy.node import Node

__all__ = ["spinning"]


@contextmanager
def spinning(executor: Executor) -> Iterator[list[Node]]:
    """The block that builds and spins a process's nodes: append each node to the yielded list.

    However the block ends (returned, failed, or stopped) the executor is shut down, every node
    appended is destroyed and rclpy is shut down. A stop is not an error: Ctrl-C, rclpy's own
    shutdown from its signal handler, and the ``RCLError`` an executor raises when that handler
    shut the context down between two waits all end the block quietly; any other error, an
    ``RCLError`` while rclpy is still up included, goes on to the caller.
    """
    nodes: list[Node] = []
    try:
        yield nodes
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except _rclpy.RCLError:
        if rclpy.ok():
            raise
    finally:
        executor.shutdown()
        for node in nodes:
            node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
