"""The AT server as the robot side runs it, with a test client, for the suites that talk to it over ROS."""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

from support.stack import robot_parts

if TYPE_CHECKING:  # tests/at_ros/at_client.py, importable while that folder's tests run
    from at_client import AtClient

__all__ = ["start_stack"]


def start_stack(ros_env: dict[str, str], deployment: str, time_scale: float) -> Iterator[AtClient]:
    """The deployment's simulation, planner and AT server as real processes, plus a test client; stops them all.

    A generator for a module fixture to ``yield from``. The client is tests/at_ros/at_client.py,
    importable while the tests of that folder run (pytest puts a test module's folder on sys.path).
    """
    from at_client import AtClient

    with robot_parts(deployment, ros_env, parts=("sim", "planner", "at-server"), time_scale=time_scale):
        client = AtClient()
        try:
            client.wait_for(
                lambda: client.status is not None and client.status.planner_node_active and bool(client.frames),
                60.0,
                "server status with an active planner",
            )
            yield client
        finally:
            client.close()
