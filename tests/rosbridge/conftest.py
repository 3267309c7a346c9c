"""Fixtures of the rosbridge tests: the real bridge process, the ROS peer node, clients."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Callable

import pytest
import roslibpy

from .rosbridge_support import bridge_url, wait_until_discovered
from support.processes import ManagedProcess, caretaker, python

PEER = Path(__file__).with_name("ros_peer.py")


@pytest.fixture(scope="package")
def peer(ros_env: dict[str, str]) -> Iterator[ManagedProcess]:
    process = python(str(PEER), env=ros_env, name="ros-peer")
    try:
        process.wait_ready(60)
        yield process
    finally:
        process.stop()


@pytest.fixture(scope="package")
def bridge(ros_env: dict[str, str], peer: ManagedProcess) -> Iterator[tuple[str, int]]:
    """A bridge on a free port, shared by all rosbridge tests (each uses its own names): (host, port)."""
    process = caretaker("bridge", "--port", "0", "--service-timeout", "5", "--set-params-glob", "/bridge_test_peer:*",
                        env=ros_env)
    try:
        process.wait_ready(60)
        url = bridge_url(process)
        host, port = url.split("//")[1].rsplit(":", 1)
        wait_until_discovered(host, int(port), "/peer/echo_in", "/peer/set_bool", "/bridge_test_peer")
        yield host, int(port)
    finally:
        process.stop()


@pytest.fixture
def connect(bridge: tuple[str, int]) -> Iterator[Callable[[], roslibpy.Ros]]:
    """Connect roslibpy clients to the bridge; all are closed at teardown."""
    clients: list[roslibpy.Ros] = []

    def open_client() -> roslibpy.Ros:
        client = roslibpy.Ros(*bridge)
        client.run(timeout=20)
        clients.append(client)
        return client

    yield open_client
    for client in clients:
        client.close()
