"""Test-side access to the ledger and its peer over real ROS 2 (an rclpy client in its own context),
the processes' fixtures (imported by name in the test modules), and a test CA for wss://."""

from __future__ import annotations

import json
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import rclpy
from caretaker_ledger_msgs.srv import CommandOutcome, ExecuteOnce
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from std_srvs.srv import Trigger

from support.processes import ManagedProcess, python
from support.spinner import Spinner

PEER = Path(__file__).with_name("ledger_peer.py")
EXECUTE = "/command_ledger/execute"
OUTCOME = "/command_ledger/outcome"
RESEND_S = 5.0
#: A ledger just started is found by DDS discovery within this (a guard: under the whole suite's
#: load a new ledger once went unseen for 30 s).
DISCOVERY_S = 90.0


class LedgerClient:
    """Calls the ledger's services and the peer's ``counts``/``release``; spins its own thread."""

    def __init__(self) -> None:
        self.context = Context()
        rclpy.init(context=self.context)
        self.node = rclpy.create_node("ledger_test_client", context=self.context)
        self.execute_client = self.node.create_client(ExecuteOnce, EXECUTE)
        self.outcome_client = self.node.create_client(CommandOutcome, OUTCOME)
        self.counts_client = self.node.create_client(Trigger, "/ledger_test/counts")
        self.release_client = self.node.create_client(Trigger, "/ledger_test/release")
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self._spinner = Spinner(self.executor, self.node, name="ledger-client")

    def _call(self, client: Any, request: Any, timeout: float) -> Any:
        """Call and wait; re-send the same request every RESEND_S without an answer.

        Every request made here may be repeated (ledger calls carry their key; the rest only
        read or release). A re-send is needed when a server has just been restarted: DDS
        still lists the killed one, and a request sent before the new one matched is lost.
        """
        assert client.wait_for_service(timeout_sec=DISCOVERY_S), f"{client.srv_name} not discovered"
        deadline = time.monotonic() + timeout
        while True:
            done = threading.Event()
            future = client.call_async(request)
            future.add_done_callback(lambda _, done=done: done.set())
            if done.wait(min(RESEND_S, max(0.0, deadline - time.monotonic()))):
                return future.result()
            client.remove_pending_request(future)
            assert time.monotonic() < deadline, f"{client.srv_name} did not answer within {timeout} s"

    def execute(
        self,
        key: str,
        service: str,
        *,
        epoch: str = "",
        type_: str = "",
        request_json: str = "",
        timeout: float = 0.0,
        wait: float = 60.0,
    ) -> Any:
        request = ExecuteOnce.Request(
            command_key=key, epoch=epoch, service=service, type=type_, request_json=request_json, timeout=timeout
        )
        return self._call(self.execute_client, request, wait)

    def execute_async(self, key: str, service: str, *, epoch: str = "") -> Any:
        """Send an execute request and return its rclpy future without waiting."""
        assert self.execute_client.wait_for_service(timeout_sec=DISCOVERY_S), "the ledger is not discovered"
        return self.execute_client.call_async(ExecuteOnce.Request(command_key=key, epoch=epoch, service=service))

    def outcome(self, key: str) -> Any:
        return self._call(self.outcome_client, CommandOutcome.Request(command_key=key), 30.0)

    def counts(self) -> dict[str, int]:
        return dict(json.loads(self._call(self.counts_client, Trigger.Request(), 30.0).message))

    def release(self) -> None:
        self._call(self.release_client, Trigger.Request(), 30.0)

    def close(self) -> None:
        self._spinner.stop()
        self.node.destroy_node()
        rclpy.shutdown(context=self.context)


@pytest.fixture(scope="module")
def peer(ros_env: dict[str, str]) -> Iterator[ManagedProcess]:
    """The counting service process (tests/ledger/ledger_peer.py)."""
    process = python(str(PEER), env=ros_env, name="ledger-peer")
    try:
        process.wait_ready(60)
        yield process
    finally:
        process.stop()


@pytest.fixture(scope="module")
def client(peer: ManagedProcess) -> Iterator[LedgerClient]:
    ledger_client = LedgerClient()
    yield ledger_client
    ledger_client.close()
