"""The two-host fixture itself: it leaves no namespace, veth or process behind, and cleans up
after dead sessions only."""

from __future__ import annotations

import subprocess

import pytest

from support.two_hosts import TwoHosts, remove_stale_namespaces


def _namespaces() -> set[str]:
    listing = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True, check=True).stdout
    return {line.split()[0] for line in listing.splitlines() if line.strip()}


def test_teardown_removes_namespaces_and_processes_even_when_the_test_fails(ros_env: dict[str, str]) -> None:
    with pytest.raises(RuntimeError, match="the test failed"), TwoHosts.create(ros_env) as hosts:
        names = {hosts.ground.namespace, hosts.link.namespace, hosts.habitat.namespace}
        assert names <= _namespaces()
        sleeper = hosts.start(hosts.habitat, ["sleep", "600"], ready=None)
        veths = {
            host.role: hosts.run(host, ["ip", "-o", "link", "show", "type", "veth"]).stdout.count("\n")
            for host in (hosts.ground, hosts.link, hosts.habitat)
        }
        assert veths == {"ground": 1, "link": 2, "habitat": 1}
        assert hosts.run(hosts.ground, ["ip", "route"]).stdout.split()[0] == "10.77.1.0/24"  # no default route
        raise RuntimeError("the test failed")
    assert not names & _namespaces()
    assert not sleeper.running
    assert not hosts.folder.exists()


def test_stale_namespaces_of_dead_sessions_only_are_removed() -> None:
    dead = subprocess.Popen(["true"])
    dead.wait()
    stale, live = f"ct2h-{dead.pid}-1-ground", "ct2h-1-1-ground"  # pid 1 always runs
    for name in (stale, live):
        subprocess.run(["ip", "netns", "add", name], check=True)
    try:
        assert stale in remove_stale_namespaces()
        assert stale not in _namespaces() and live in _namespaces()
    finally:
        for name in (stale, live):
            subprocess.run(["ip", "netns", "delete", name], capture_output=True)
