"""The web view's own rosbridge link (console/spatial_link.py) to a bridge with TLS and a
shared secret, set up from a binding file as PAX's is: it authenticates with HMAC over wss,
gets a latched value, calls a service; with the wrong secret it never counts as connected."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest

from caretaker.processes import REPO
from console.spatial_link import read_view_link
from rosbridge_wire.client import LinkError, RosbridgeClient, Subscription
from support.certificates import self_signed_certificate
from support.processes import ManagedProcess, caretaker

from .rosbridge_support import bridge_url

SECRET = "view-link-secret"


@pytest.fixture(scope="module")
def secure_bridge(
    ros_env: dict[str, str], peer: ManagedProcess, tmp_path_factory: pytest.TempPathFactory
) -> Iterator[tuple[str, Path]]:
    """wss:// with a self-signed certificate and HMAC auth: (URL, folder with ca.pem)."""
    folder = tmp_path_factory.mktemp("view-link")
    cert, key = self_signed_certificate(folder, "ca.pem")
    (folder / "bridge.secret").write_text(SECRET + "\n")
    process = caretaker(
        "bridge",
        "--port",
        "0",
        "--certfile",
        str(cert),
        "--keyfile",
        str(key),
        "--auth-secret-file",
        str(folder / "bridge.secret"),
        env=ros_env,
    )
    try:
        process.wait_ready(60)
        yield bridge_url(process).replace("ws://", "wss://"), folder
    finally:
        process.stop()


def binding(folder: Path, url: str, secret: str) -> Path:
    (folder / "view.secret").write_text(secret + "\n")
    path = folder / f"binding-{len(secret)}.yaml"
    path.write_text(f"""robot: test
rosbridge: {url}
link:
  one_way_delay: 0.2
security:
  ca_file: ca.pem
  secret_file: view.secret
systems:
- sysrep: {REPO / "sysrep" / "affordance_templates.yaml"}
  plugins: [at_commands]
  namespace: /arm7/affordance_template_server
""")
    return path


async def read(url: str, binding_path: Path, *, timeout: float) -> tuple[list[str], list[Any], Any]:
    link = read_view_link(binding_path)
    assert link is not None and link.namespace == "/arm7" and link.name("joint_states") == "/arm7/joint_states"
    states: list[str] = []
    latched: list[Any] = []
    connected, arrived = asyncio.Event(), asyncio.Event()

    def on_latched(message: Any) -> None:
        latched.append(message)
        arrived.set()

    def on_state(state: str) -> None:
        states.append(state)
        if state == "connected":
            connected.set()

    rosbridge = RosbridgeClient(link.endpoint, name="view-test", on_state=on_state)
    rosbridge.subscribe(Subscription("/peer/latched", "std_msgs/msg/String", on_latched))
    rosbridge.start()
    answer = None
    try:
        await asyncio.wait_for(connected.wait(), timeout)
        answer = await rosbridge.call("/rosapi/get_ros_version", {})
        # the latched message comes once the bridge's subscriber has discovered the publisher,
        # which a loaded machine can take seconds to do
        await asyncio.wait_for(arrived.wait(), timeout)
    except TimeoutError:
        pass
    finally:
        await rosbridge.close()
    return states, latched, answer


def run(url: str, binding_path: Path, *, timeout: float) -> tuple[list[str], list[Any], Any]:
    """``read`` on its own event loop in a thread (a Playwright session may own this thread's loop)."""
    with ThreadPoolExecutor(1) as pool:
        return pool.submit(asyncio.run, read(url, binding_path, timeout=timeout)).result()


def test_the_view_link_authenticates_over_tls_as_the_binding_says(secure_bridge: tuple[str, Path]) -> None:
    url, folder = secure_bridge
    states, latched, answer = run(url, binding(folder, url, SECRET), timeout=30)
    assert states[0] == "connected"
    assert latched == [{"data": "latched value"}]
    assert answer is not None and answer["version"]


def test_a_wrong_secret_never_connects(secure_bridge: tuple[str, Path]) -> None:
    url, folder = secure_bridge
    states, latched, answer = run(url, binding(folder, url, "not-the-secret"), timeout=4)
    assert "connected" not in states and latched == [] and answer is None
    assert "reconnecting" in states  # refused, and it keeps trying (the next auth is a fresh one)


async def serve_and_call(url: str, binding_path: Path) -> tuple[Any, str, Any]:
    """One client serves a service through the bridge, another calls it: (an answer, what a call
    the handler failed ended in, the answer to the next call)."""
    link = read_view_link(binding_path)
    assert link is not None

    async def served(args: Any) -> dict[str, Any]:
        if not args["data"]:
            raise ValueError("refused: data is false")
        return {"success": True, "message": "served by the client"}

    server = RosbridgeClient(link.endpoint, name="serving-client")
    server.advertise_service("/view_test/served", "std_srvs/srv/SetBool", served)
    caller = RosbridgeClient(link.endpoint, name="calling-client")
    server.start()
    caller.start()
    try:
        await asyncio.wait_for(asyncio.gather(server.ready.wait(), caller.ready.wait()), 30)
        answer = None
        while answer is None:  # the bridge knows the service once DDS has discovered the advertisement
            try:
                answer = await caller.call("/view_test/served", {"data": True})
            except LinkError as exc:
                assert "not advertised" in str(exc) or "no service" in str(exc) or "not available" in str(exc), exc
        with pytest.raises(LinkError) as refused:  # a ROS service cannot fail: its caller hears nothing
            await caller.call("/view_test/served", {"data": False}, timeout=3)
        return answer, str(refused.value), await caller.call("/view_test/served", {"data": True})
    finally:
        await caller.close()
        await server.close()


def test_a_client_serves_a_service_and_outlives_a_failing_handler(secure_bridge: tuple[str, Path]) -> None:
    url, folder = secure_bridge
    with ThreadPoolExecutor(1) as pool:
        answer, refused, after = pool.submit(asyncio.run, serve_and_call(url, binding(folder, url, SECRET))).result()
    assert answer == after == {"success": True, "message": "served by the client"}
    assert "Timeout exceeded" in refused or "no answer in time" in refused, refused


async def call_behind_the_login(url: str, binding_path: Path) -> tuple[Any, str]:
    """A call sent as soon as the login has gone out, not waiting for the bridge's first answer:
    (its answer, or what it ended in)."""
    link = read_view_link(binding_path)
    assert link is not None
    client = RosbridgeClient(link.endpoint, name="pipelining-client")
    client.start()
    try:
        await asyncio.wait_for(client.opened.wait(), 30)
        try:
            return await client.call("/rosapi/get_ros_version", {}, timeout=10), ""
        except LinkError as exc:
            return None, str(exc)
    finally:
        await client.close()


def test_a_call_right_behind_the_login_is_answered_after_it_and_never_behind_a_refused_one(
    secure_bridge: tuple[str, Path],
) -> None:
    url, folder = secure_bridge
    with ThreadPoolExecutor(1) as pool:
        answer, _ = pool.submit(asyncio.run, call_behind_the_login(url, binding(folder, url, SECRET))).result()
        refused, why = pool.submit(asyncio.run, call_behind_the_login(url, binding(folder, url, "wrong"))).result()
    assert answer is not None and answer["version"]
    assert refused is None and "connection was lost" in why, why  # the bridge closed it unanswered
