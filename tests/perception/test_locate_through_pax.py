"""Across rosbridge: the perception SysRep served by the Java ROS-convention plugin (and the
ledger), and the demo's world checks measuring the displaced world where it really is.

What a procedure sees: ``perception.locate`` with the binding's arguments gives the pose as
result values (x, y, z in m; roll, pitch, yaw in rad; the residual in px; the markers used) and
the last result as telemetry; a refusal is a failed command with the reason and no pose. Real
parts: the JVM with the plugins, the rosbridge server, the command ledger, perception and the
simulator (the module's stack, conftest.py).
"""

from __future__ import annotations

import queue
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from perception_client import PerceptionClient, errors, located

from caretaker.stack import Stack
from caretaker.world_checks import FrameCheck, Place, watch_world
from pride.pax_host import PaxHost
from pride.systems import Outcome, TelemetryValue
from sim.scene import load_scene

pytestmark = pytest.mark.slow(seconds=60)

BINDING = Path(__file__).resolve().parents[2] / "sysrep" / "bindings" / "iva.yaml"


def test_world_checks_measure_where_things_really_are(stack: Stack, client: PerceptionClient) -> None:
    """``caretaker demo``'s end-of-run checks read sim/check/frames, not the world model."""
    scene = load_scene(stack.deployment.scene)
    nominal = scene.slots["cabinet/slot"].pose
    checks = (
        FrameCheck("filter/CDRA-F-0007", Place("cabinet/slot"), 5.0, 1.0, during_run=False),
        FrameCheck("filter/CDRA-F-0007", Place("world", nominal.xyz, nominal.rpy, named=False), 5.0, None, False),
    )
    with watch_world(checks, stack.bridge_url, "", scene) as world:
        seated, where_drawn = world.judge("sqlite://", "no run")
    assert seated.holds, seated.words
    offset = float(np.linalg.norm(client.truth("cabinet/slot")[:3, 3] - np.array(nominal.xyz)) * 1000)
    assert not where_drawn.holds and f"{offset:.0f} mm from it" in where_drawn.words, where_drawn.words


@pytest.fixture(scope="module")
def host(stack: Stack) -> Iterator[PaxHost]:
    h = PaxHost(BINDING, rosbridge_url=stack.bridge_url)
    try:
        yield h
    finally:
        h.close()


def test_locate_gives_the_pose_as_result_values(host: PaxHost, client: PerceptionClient) -> None:
    changes: queue.Queue[tuple[str, TelemetryValue]] = queue.Queue()
    host.add_listener(lambda sysrep, item, value: changes.put((item, value)) if sysrep == "perception" else None)
    args = {"object": "cabinet/slot", "camera": "cabinet_slot_60cm_left", "frame": "world", "tolerance_px": 1.0}
    result = host.execute("perception", "locate", args)
    assert result.success, result.message
    values = result.values
    mm, deg = errors(located(values), client.truth("cabinet/slot"))
    assert mm <= 5.0 and deg <= 1.0, f"{result.message}: {mm:.2f} mm and {deg:.3f} deg from the truth"
    assert values["markers"] == "7,8" and values["frame"] == "world" and 0 < values["residual_px"] <= 1.0
    assert "located from cabinet_slot_60cm_left" in result.message
    # the telemetry of the last result, as a procedure's verify reads it (each item arrives on its own)
    wanted = {"last_object": "cabinet/slot", "last_success": True, "last_residual_px": values["residual_px"]}
    seen: dict[str, object] = {}
    while any(seen.get(item) != pytest.approx(value) for item, value in wanted.items()):
        item, value = changes.get(timeout=30.0)
        seen[item] = value.value
    assert host.telemetry("perception", "last_residual_px").value == pytest.approx(values["residual_px"])


def test_a_refusal_is_a_failed_command_with_its_reason(host: PaxHost) -> None:
    args = {"object": "rack/slot_1", "camera": "cabinet_slot_60cm_left", "frame": "world", "tolerance_px": 0.0}
    result = host.execute("perception", "locate", args)
    assert result.outcome is Outcome.FAILED
    assert "none of its markers (1, 2) is seen" in result.message and not result.values
