"""Light time as a parameter: waits across the link grow with its delay, and a habitat's bridge gives
clients bound to a long link the time their handshakes need."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from bridge.rosbridge.limits import Limits
from caretaker.deployment import load_deployment
from caretaker.stack import _light_time_limits
from rosbridge_wire.light_time import LightTime
from support.procedures import REPO


@pytest.mark.parametrize("delay", [0.0, 1.3, 45.0, 600.0, 1440.0])
def test_every_wait_across_the_link_covers_the_round_trips_it_needs(delay: float) -> None:
    light = LightTime(delay)
    assert light.connect_within >= 4 * 2 * delay + 10  # TCP, TLS, upgrade, login: four round trips and more
    assert light.answer_within(10) == 10 + 2 * delay
    assert light.keepalive_timeout > light.keepalive + 2 * delay
    limits = light.bridge_limits()
    assert limits["handshake_timeout"] >= 3 * 2 * delay and limits["auth_timeout"] >= 2 * delay
    assert limits["ping_timeout"] > light.keepalive + 2 * delay


def _deployment_with_link(tmp_path: Path, delay: float) -> Path:
    binding = yaml.safe_load((REPO / "sysrep" / "bindings" / "iva.yaml").read_text())
    binding["link"] = {"one_way_delay": delay}
    for system in binding["systems"]:
        system["sysrep"] = str((REPO / "sysrep" / "bindings" / system["sysrep"]).resolve())
    (tmp_path / "far.yaml").write_text(yaml.safe_dump(binding))
    deployment = yaml.safe_load((REPO / "deployments" / "iva.yaml").read_text())
    for key in ("scene", "robot", "templates", "robots"):
        if key in deployment:
            deployment[key] = str((REPO / "deployments" / deployment[key]).resolve())
    deployment["bindings"] = [str(tmp_path / "far.yaml")]
    deployment.pop("demo", None)
    path = tmp_path / "far-habitat.yaml"
    path.write_text(yaml.safe_dump(deployment))
    return path


def test_a_habitat_bridge_serving_a_long_link_gives_its_clients_the_time_they_need(tmp_path: Path) -> None:
    near = load_deployment(REPO / "deployments" / "iva.yaml")
    assert _light_time_limits(near) == []  # the Moon's 1.3 s fits the bridge's defaults
    far = _light_time_limits(load_deployment(_deployment_with_link(tmp_path, 45.0)))
    given = dict(zip(far[::2], (float(v) for v in far[1::2]), strict=True))
    assert given["--handshake-timeout"] >= 3 * 90 > Limits().handshake_timeout
    assert given["--auth-timeout"] >= 90 > Limits().auth_timeout
    assert given["--ping-timeout"] > 180 + 90
