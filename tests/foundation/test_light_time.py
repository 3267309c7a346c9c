"""Light time as a parameter: waits across the link grow with its delay, and a habitat's bridge gives
clients bound to a long link the time their handshakes need and takes their logins, which arrive
one light time old; an approval carried up in an onboard unit is good for as long after the unit's
trip as on a short link."""

from __future__ import annotations

import time
from datetime import UTC, datetime
from pathlib import Path

import pytest
import yaml

from bridge.rosbridge.limits import Limits
from bridge.rosbridge.protocol import Refused
from bridge.rosbridge.security import Authenticator
from caretaker.deployment import load_deployment
from caretaker.stack import _light_time_limits
from onboard.downlink import build_unit
from pride.approvals import ApprovalPolicy, CriticalLevel
from pride.run_setup import load_sysreps
from procedure_language.lint import check_procedure
from rosbridge_wire import LOGIN_LIFETIME_S, signed_login
from rosbridge_wire.client import Endpoint, RosbridgeClient
from rosbridge_wire.light_time import LightTime
from support.procedures import FIXTURES, REPO

SECRET = "shared-with-the-habitat"


@pytest.mark.parametrize("delay", [0.0, 1.3, 45.0, 600.0, 1440.0])
def test_every_wait_across_the_link_covers_the_round_trips_it_needs(delay: float) -> None:
    light = LightTime(delay)
    assert light.connect_within >= 4 * 2 * delay + 10  # TCP, TLS, upgrade, login: four round trips and more
    assert light.answer_within(10) == 10 + 2 * delay
    assert light.keepalive_timeout > light.keepalive + 2 * delay
    limits = light.bridge_limits()
    assert limits["handshake_timeout"] >= 3 * 2 * delay and limits["auth_timeout"] >= 2 * delay
    assert limits["ping_timeout"] > light.keepalive + 2 * delay
    assert light.login_lifetime == limits["login_max_age"] == LOGIN_LIFETIME_S + delay
    assert light.uplink_within == light.connect_within + delay  # a unit goes up once connected, one way


@pytest.mark.parametrize("delay", [0.0, 60.0, 600.0])
def test_an_approval_carried_up_is_good_for_its_time_after_the_units_trip(delay: float) -> None:
    light, given = LightTime(delay), datetime(2031, 5, 1, 12, tzinfo=UTC)
    policy = ApprovalPolicy(CriticalLevel.HAZARDOUS, expires_s=300, clock=lambda: given)
    unit = build_unit(
        check_procedure(FIXTURES / "lab_all_kinds.xml", load_sysreps([REPO / "sysrep", FIXTURES / "sysrep"])),
        run_id="lab-far",
        binding="lab.yaml",
        user="alice",
        mode="autonomous",
        values={},
        confirm_manual=True,
        confirm_hazardous=True,
        breakpoints=(),
        lifetime_s=300 + light.uplink_within,
        now=given.timestamp(),
        policy=policy,
        approver="bob",
        in_transit=light.uplink_within,
    )
    assert unit.approvals, "the lab procedure's hazardous vent goes up approved"
    for approval in unit.approvals:
        assert approval.approved_at == given.timestamp()
        assert approval.expires_at == given.timestamp() + light.uplink_within + 300


@pytest.mark.parametrize("delay", [1.3, 14.0, 60.0, 600.0])
def test_a_login_signed_far_away_arrives_valid_at_a_bridge_that_allows_the_light_time(delay: float) -> None:
    light = LightTime(delay)
    client = RosbridgeClient(Endpoint("wss://habitat:9090", delay, secret=SECRET), name="far-client")
    login = client._auth_message()
    assert login is not None and login["end"] - login["t"] == pytest.approx(light.login_lifetime)
    # such a login as the bridge reads it: one delay after it was signed
    signed = time.time() - delay
    arrived = signed_login(SECRET, "far-client", "wss://habitat:9090", signed, lifetime=light.login_lifetime)
    Authenticator(SECRET, max_age=light.bridge_limits()["login_max_age"]).check(arrived)
    if delay >= LOGIN_LIFETIME_S:  # a bridge at its defaults, or a login valid as long as on a short link: refused
        with pytest.raises(Refused, match="expired or its clock is off"):
            Authenticator(SECRET, max_age=Limits().login_max_age).check(arrived)
        short = signed_login(SECRET, "far-client", "wss://habitat:9090", time.time() - delay)
        with pytest.raises(Refused, match="expired or its clock is off"):
            Authenticator(SECRET, max_age=light.bridge_limits()["login_max_age"]).check(short)


def test_a_bridge_refuses_a_login_older_than_its_light_time_allows_or_from_the_future() -> None:
    far = Authenticator(SECRET, max_age=LightTime(60.0).bridge_limits()["login_max_age"])
    now = time.time()
    for signed in (now - 121, now + 61):
        with pytest.raises(Refused, match="expired or its clock is off"):
            far.check(signed_login(SECRET, "far-client", "wss://habitat:9090", signed, lifetime=600))


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
    assert _light_time_limits(near) == []  # its binding: the habitat's own, no link
    far = _light_time_limits(load_deployment(_deployment_with_link(tmp_path, 45.0)))
    given = dict(zip(far[::2], (float(v) for v in far[1::2]), strict=True))
    assert given["--handshake-timeout"] >= 3 * 90 > Limits().handshake_timeout
    assert given["--auth-timeout"] >= 90 > Limits().auth_timeout
    assert given["--ping-timeout"] > 180 + 90
    assert given["--login-max-age"] == 60 + 45 > Limits().login_max_age
