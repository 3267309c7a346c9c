"""Ground and habitat on two hosts (network namespaces) joined only by the link emulator.

Habitat: the ROS peer node and a real ``caretaker bridge``. Link: ``caretaker link`` with a
0.2 s one-way delay. Ground: a roslibpy client (ground_probe.py) and an rclpy node that must
see no ROS graph. Outages are started through the link's control socket.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from caretaker.link.control import JsonLineClient
from support.two_hosts import Host, LinkProcess, TwoHosts

pytestmark = [pytest.mark.ros, pytest.mark.slow]

HERE = Path(__file__).parent
PEER = HERE.parent / "rosbridge" / "ros_peer.py"
DELAY = 0.2
BRIDGE_PORT = 9090


@dataclass
class Scene:
    hosts: TwoHosts
    link: LinkProcess
    probe: JsonLineClient

    def ask(self, op: str, **request: Any) -> dict[str, Any]:
        """One request to the ground probe; fails the test with its error if it failed."""
        return self.probe.request({"op": op, **request})

    def connected(self) -> dict[str, Any]:
        """The probe's status, after connecting it through the link if it is not connected."""
        if not self.ask("status")["connected"]:
            self.ask("connect", url=self.link.url, timeout=60)
        status: dict[str, Any] = self.ask("status")
        return status

    def graph(self, host: Host, **options: str) -> dict[str, list[str]]:
        argv = [str(HERE / "graph_probe.py"), "--name", f"graph_probe_{host.role}"]
        argv += [item for key, value in options.items() for item in (f"--{key.replace('_', '-')}", value)]
        output = self.hosts.run(host, [sys.executable, *argv]).stdout
        line = next(line for line in output.splitlines() if line.startswith("GRAPH "))
        graph: dict[str, list[str]] = json.loads(line.removeprefix("GRAPH "))
        return graph


@pytest.fixture(scope="module")
def scene(ros_env: dict[str, str]) -> Iterator[Scene]:
    with TwoHosts.create(ros_env) as hosts:
        hosts.python(hosts.habitat, str(PEER))
        hosts.caretaker(
            hosts.habitat,
            "bridge",
            "--address",
            hosts.habitat.address,
            "--port",
            str(BRIDGE_PORT),
            "--service-timeout",
            "20",
            "--insecure",
        )  # a test link: no TLS, no secret
        link = hosts.start_link(target_port=BRIDGE_PORT, delay=DELAY, options=["--seed", "1"])
        probe = hosts.folder / "probe.sock"
        hosts.python(hosts.ground, str(HERE / "ground_probe.py"), str(probe))
        yield Scene(hosts, link, JsonLineClient(probe, timeout=120))


def test_the_ground_sees_no_ros_graph_and_reaches_the_habitat_only_through_the_link(scene: Scene) -> None:
    habitat = scene.graph(scene.hosts.habitat, wait_for="/bridge_test_peer", seconds="60")
    assert "/bridge_test_peer" in habitat["nodes"] and "/peer/echo_in" in habitat["topics"]
    ground = scene.graph(scene.hosts.ground, seconds="5")
    assert ground["nodes"] == ["/graph_probe_ground"]
    assert not [name for name in ground["topics"] + ground["services"] if name.startswith("/peer")]

    direct = scene.ask("tcp", host=scene.hosts.habitat.address, port=BRIDGE_PORT)["ending"]
    assert "unreachable" in direct.lower(), direct
    assert scene.ask("tcp", host=scene.link.address[0], port=scene.link.address[1])["ending"] == "answered"


def test_a_ground_client_gets_topics_and_services_through_the_delayed_link(scene: Scene) -> None:
    scene.connected()
    echo = scene.ask("echo", data="hello habitat", timeout=60)
    assert echo["data"] == "hello habitat" and echo["seconds"] >= 2 * DELAY
    call = scene.ask("call", service="/peer/set_bool", type="std_srvs/SetBool", args={"data": True}, timeout=60)
    assert call["values"] == {"success": True, "message": "got true"} and call["seconds"] >= 2 * DELAY
    stats = scene.link.control.stats()
    ground = [c for c in stats.connections if c.peer.startswith(scene.hosts.ground.address + ":")]
    assert ground and ground[-1].up_bytes > 0 and ground[-1].down_bytes > 0
    assert stats.up_bytes == sum(c.up_bytes for c in stats.connections)


def test_a_hold_delivers_late_on_the_same_connection(scene: Scene) -> None:
    before = scene.connected()
    connections = len(scene.link.control.stats().connections)
    scene.link.control.hold(2.0)
    call = scene.ask("call", service="/peer/set_bool", type="std_srvs/SetBool", args={"data": False}, timeout=60)
    assert call["values"] == {"success": False, "message": "got false"}
    assert call["seconds"] >= 2.0
    after = scene.ask("status")
    assert after["connected"] and after["events"] == before["events"]  # no close, no reconnect
    stats = scene.link.control.stats()
    assert len(stats.connections) == connections and stats.holds == 1


def test_a_reset_closes_the_client_and_refuses_connections_for_its_length(scene: Scene) -> None:
    events = scene.connected()["events"]
    scene.link.control.reset(3.0)
    scene.ask("wait", event="close", count=events.get("close", 0) + 1, timeout=30)
    assert scene.ask("tcp", host=scene.link.address[0], port=scene.link.address[1])["ending"] == "reset"
    stats = scene.link.control.stats()
    assert stats.resets == 1 and stats.refused >= 1 and not stats.open_connections
    # roslibpy reconnects by itself once the link accepts connections again
    scene.ask("wait", event="ready", count=events["ready"] + 1, timeout=60)
    call = scene.ask("call", service="/peer/set_bool", type="std_srvs/SetBool", args={"data": True}, timeout=60)
    assert call["values"]["message"] == "got true"
