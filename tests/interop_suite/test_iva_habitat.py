"""``caretaker interop`` against a running ``caretaker up`` of the IVA habitat deployment (wss://,
a secret), from another network namespace than the server: every profile passes, the ``at``
profile on the IVA robot, and the ``link`` profile through ``caretaker link`` at 1.3 s one way
with loss and a 30 s outage.

The habitat namespace runs the stack as tests/flight/ starts it. The direct run is made from the
link namespace, which reaches the habitat's address without a relay, so only the network
namespace boundary and the bridge's TLS and auth stand between them; the ``link`` run is made
from the ground namespace, whose only way to the habitat is the link.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import pytest

from caretaker.certs import make_link_credentials
from flight.flight_support import BRIDGE_PORT, start_habitat, write_ground_binding
from interop.catalog import PROFILES
from support.two_hosts import TwoHosts

from .suite_support import assert_complete, finish_suite, start_suite

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=180)]

DELAY = 1.3
OUTAGE = 30


@dataclass(frozen=True)
class Habitat:
    hosts: TwoHosts
    credentials: dict[str, Path]

    @property
    def url(self) -> str:
        return f"wss://{self.hosts.habitat.address}:{BRIDGE_PORT}"

    def auth_options(self) -> list[str]:
        return ["--secret-file", str(self.credentials["rosbridge.secret"]), "--ca", str(self.credentials["ca.pem"])]


@pytest.fixture(scope="module")
def habitat(ros_env: dict[str, str]) -> Iterator[Habitat]:
    with TwoHosts.create(ros_env) as hosts:
        credentials = make_link_credentials(hosts.folder / "link", [hosts.habitat.address, hosts.link.address], days=2)
        binding = write_ground_binding(
            hosts.folder, f"wss://{hosts.link.address}:{BRIDGE_PORT}", credentials, one_way_delay=0.2, outage_budget=120
        )
        start_habitat(hosts, credentials, binding, hosts.folder / "habitat-state", time_scale="1", onboard=False)
        yield Habitat(hosts, credentials)


def test_every_profile_passes_from_another_namespace(habitat: Habitat, tmp_path: Path) -> None:
    report = tmp_path / "report"
    direct = tuple(profile for profile in PROFILES if profile != "link")  # link: the next test
    run = finish_suite(
        start_suite(
            habitat.url,
            report,
            "caretaker-iva",
            "--profile",
            ",".join(direct),
            *habitat.auth_options(),
            env=dict(os.environ),
            prefix=["ip", "netns", "exec", habitat.hosts.link.namespace],
        ),
        report,
        "caretaker-iva",
        timeout=300,
    )
    assert_complete(run, direct)
    not_passing = {case: o for case, o in run.outcomes().items() if o not in ("OK", "NON-STRICT", "INFORMATIONAL")}
    assert not not_passing, f"{not_passing}\n{run.output[-4000:]}"
    assert run.returncode == 0, run.output[-2000:]


def test_the_link_profile_passes_across_a_long_lossy_link_with_an_outage(habitat: Habitat, tmp_path: Path) -> None:
    hosts = habitat.hosts
    # the hold starts once the cases' connections are open (all run at once), so several of them
    # must ride it out (the bridge closes a client that has not authenticated within 20 s)
    options = ["--loss", "0.05", "--seed", "43", "--outage", f"hold:{OUTAGE}@40"]
    link = hosts.start_link(target_port=BRIDGE_PORT, port=BRIDGE_PORT, delay=DELAY, options=options)
    report = tmp_path / "report"
    link_options = ["--link-delay", str(DELAY), "--outage", str(OUTAGE), "--quiet", str(OUTAGE)]
    run = finish_suite(
        start_suite(
            f"wss://{link.address[0]}:{link.address[1]}",
            report,
            "caretaker-iva-over-the-link",
            "--profile",
            "link",
            *habitat.auth_options(),
            *link_options,
            env=dict(os.environ),
            prefix=["ip", "netns", "exec", hosts.ground.namespace],
        ),
        report,
        "caretaker-iva-over-the-link",
        timeout=900,
    )
    assert_complete(run, ("link",))
    assert link.control.stats().holds >= 1, "the outage never happened during the run"
    not_passing = {case: o for case, o in run.outcomes().items() if o not in ("OK", "NON-STRICT", "INFORMATIONAL")}
    assert not not_passing, f"{not_passing}\n{run.output[-4000:]}"
    assert run.returncode == 0, run.output[-2000:]
