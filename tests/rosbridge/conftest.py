"""Fixtures of the rosbridge tests: the real bridge process, the ROS peer node, clients."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
import roslibpy

from support.processes import ManagedProcess, caretaker, python

from .hostile import HOSTILE_LIMITS, BridgeLog, Watch
from .rosbridge_support import bridge_url, wait_until_discovered

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
    process = caretaker(
        "bridge", "--port", "0", "--service-timeout", "5", "--set-params-glob", "/bridge_test_peer:*", env=ros_env
    )
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


@pytest.fixture(scope="package")
def hostile_bridge(
    ros_env: dict[str, str], peer: ManagedProcess
) -> Iterator[tuple[ManagedProcess, BridgeLog, tuple[str, int]]]:
    """A bridge with small quotas for the fuzz tests, its log counted: (process, log, address)."""
    bridge_log = BridgeLog()
    process = caretaker(
        "bridge",
        "--port",
        "0",
        "--node-name",
        "rosbridge_hostile",  # the package's bridge, with the default name, runs beside it
        "--service-timeout",
        "1",
        *HOSTILE_LIMITS,
        env=ros_env,
        on_line=bridge_log,
    )
    try:
        process.wait_ready(60)
        host, port = bridge_url(process).split("//")[1].rsplit(":", 1)
        wait_until_discovered(host, int(port), "/peer/echo_in", "/peer/set_bool", "/bridge_test_peer")
        yield process, bridge_log, (host, int(port))
    finally:
        process.stop()


@pytest.fixture
def watch(hostile_bridge: tuple[ManagedProcess, BridgeLog, tuple[str, int]]) -> Iterator[Watch]:
    """A well-formed client calling the hostile bridge while the test attacks it; afterwards the
    bridge's work while a call waited, the RSS growth and the tracebacks logged are checked."""
    process, bridge_log, address = hostile_bridge
    tracebacks_before = bridge_log.snapshot()[1]
    with Watch(process.proc.pid, address) as watching:
        yield watching
    watching.check()
    assert bridge_log.snapshot()[1] == tracebacks_before, f"the bridge logged a traceback:\n{process.tail()}"
    assert process.running
