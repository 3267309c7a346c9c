"""``caretaker up DEPLOYMENT`` supervises its parts: a dead AT server comes back with its
instances, a dead rosbridge on the port it had,
a dead simulation (the world) ends the stack, and nothing outlives it."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from urllib.parse import urlparse

import psutil
import pytest
import roslibpy

from rosbridge.rosbridge_support import wait_until_discovered
from support.processes import COMMAND_HANG_S, ManagedProcess
from support.stack import stack_up

pytestmark = [pytest.mark.ros, pytest.mark.slow]


@pytest.fixture
def stack(ros_env: dict[str, str]) -> Iterator[tuple[ManagedProcess, int]]:
    with stack_up("iva", ros_env) as up:
        port = urlparse(up.url).port
        assert port
        # READY means each part is up, not that DDS has shown the AT server to the bridge yet
        wait_until_discovered(
            "127.0.0.1",
            port,
            "/affordance_template_server/status",
            "/affordance_template_server/add_template",
            "/affordance_template_server",
            timeout=COMMAND_HANG_S,
        )
        yield up.process, port


def _part(up: ManagedProcess, subcommand: str) -> psutil.Process:
    """The stack's child process running ``caretaker SUBCOMMAND``."""
    children = psutil.Process(up.proc.pid).children(recursive=True)
    matches = [c for c in children if subcommand in c.cmdline()]
    assert len(matches) == 1, [c.cmdline() for c in children]
    return matches[0]


def _call(port: int, service: str, service_type: str, args: dict) -> dict:
    ros = roslibpy.Ros(host="127.0.0.1", port=port)
    ros.run(30)
    try:
        return roslibpy.Service(ros, service, service_type).call(roslibpy.ServiceRequest(args), timeout=30)
    finally:
        ros.close()


def _call_until_answered(
    port: int, service: str, service_type: str, args: dict, attempts: int = 6
) -> tuple[dict | None, list[str]]:
    """Call until the service answers; the failures before that.

    A request sent in the first moments after a server restarts can be lost in DDS: the dead
    server's endpoints stay in the graph until their lease runs out, so the service looks
    available before the new server has matched the bridge's request writer. The bridge answers
    such a call with a timeout failure (after its default 10 s), or says the server was lost when
    it notices the dead one first; never silence or success.
    """
    failures: list[str] = []
    for _ in range(attempts):
        try:
            return _call(port, service, service_type, args), failures
        except roslibpy.core.ServiceException as exc:
            failures.append(str(exc))
    return None, failures


def test_a_dead_at_server_is_restarted_with_its_instances(stack: tuple[ManagedProcess, int]) -> None:
    up, port = stack
    added = _call(
        port,
        "/affordance_template_server/add_template",
        "affordance_template_msgs/srv/AddAffordanceTemplate",
        {"class_type": "cdra_filter"},
    )
    assert added["success"], added
    old = _part(up, "at-server")
    old.send_signal(signal.SIGKILL)
    up.wait_for_line(r"^at-server died \(exit -9\); restarting it$", 30)
    up.wait_for_line(r"^restarted at-server: READY at-server ur10$", 120)
    assert _part(up, "at-server").pid != old.pid
    running, failures = _call_until_answered(
        port,
        "/affordance_template_server/get_running",
        "affordance_template_msgs/srv/GetRunningAffordanceTemplates",
        {},
    )
    assert running is not None, f"get_running never answered after the restart: {failures}\n{up.tail(80)}"
    # answered as failures, never silence: a timeout, or the dead server noticed mid-call
    assert all("Timeout exceeded" in f or "lost its server before answering" in f for f in failures), failures
    assert added["instance"] in running["templates"]
    assert up.running


def test_a_dead_bridge_comes_back_on_the_port_it_picked(stack: tuple[ManagedProcess, int]) -> None:
    up, port = stack
    _part(up, "bridge").send_signal(signal.SIGKILL)
    up.wait_for_line(rf"^restarted bridge: READY bridge ws://127\.0\.0\.1:{port}$", 120)
    answer, failures = _call_until_answered(
        port,
        "/affordance_template_server/get_running",
        "affordance_template_msgs/srv/GetRunningAffordanceTemplates",
        {},
    )
    assert answer is not None and answer["success"], failures


def test_a_dead_simulation_ends_the_stack_and_every_part(stack: tuple[ManagedProcess, int]) -> None:
    up, _ = stack
    parts = psutil.Process(up.proc.pid).children(recursive=True)
    _part(up, "sim").send_signal(signal.SIGKILL)
    assert up.proc.wait(timeout=COMMAND_HANG_S) == 1
    assert "caretaker up: sim died" in up.tail()
    _, alive = psutil.wait_procs(parts, timeout=30)
    assert not alive, [p.cmdline() for p in alive]
