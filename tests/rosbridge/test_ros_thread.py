"""RosThread.on_server_thread: requests of server_node's action clients leave from the thread
that executes those clients, so their answers cannot be taken before they are on record."""

from __future__ import annotations

import asyncio
import threading
from collections.abc import Awaitable, Callable

import pytest

from bridge.rosbridge.ros_thread import RosThread


def run_with_ros(work: Callable[[RosThread], Awaitable[object]]) -> object:
    async def main() -> object:
        ros = RosThread(asyncio.get_running_loop(), node_name="ros_thread_test")
        try:
            return await work(ros)
        finally:
            ros.shutdown()

    return asyncio.run(main())


def test_the_function_runs_on_the_thread_that_executes_server_node() -> None:
    async def work(ros: RosThread) -> tuple[str, str]:
        return await ros.on_server_thread(lambda: threading.current_thread().name), threading.current_thread().name

    ran_on, awaited_on = run_with_ros(work)
    assert ran_on == "ros-servers" and awaited_on != ran_on


def test_its_failure_reaches_the_awaiting_side() -> None:
    def fail() -> None:
        raise ValueError("refused on the ROS side")

    async def work(ros: RosThread) -> None:
        await ros.on_server_thread(fail)

    with pytest.raises(ValueError, match="refused on the ROS side"):
        run_with_ros(work)
