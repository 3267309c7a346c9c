"""The paper's two demonstrations complete end to end, and the world ends as the procedure says.

Each runs ``caretaker demo`` exactly as the README tells a newcomer (simulation as fast as
possible): separate processes for the simulation, planner, AT server, rosbridge and the
procedure runner with its JVM. ``caretaker demo`` exits 0 only if the procedure completed AND
its own check of the world holds, so these tests also read what it verified.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from caretaker.processes import REPO
from support.processes import caretaker

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=120)]


def _demo(scenario: str, tmp_path: Path, env: dict[str, str]) -> list[str]:
    db = f"sqlite:///{tmp_path / 'audit.db'}"
    # As the README tells it: the shipped deployment file (the port 0: tests run side by side).
    proc = caretaker(
        "demo",
        str(REPO / "deployments" / f"{scenario}.yaml"),
        "--db",
        db,
        "--reports",
        str(tmp_path / "reports"),
        "--bridge-port",
        "0",
        env=env,
        name=f"demo-{scenario}",
    )
    try:
        proc.proc.wait(timeout=420)
    finally:
        proc.stop()
    output = list(proc.output)
    assert proc.proc.returncode == 0, f"demo {scenario} failed:\n" + "\n".join(output[-60:])
    return output


def test_iva_cdra_filter_replacement(tmp_path: Path, ros_env: dict[str, str]) -> None:
    output = _demo("iva", tmp_path, ros_env)
    verified = [line for line in output if "verified:" in line]
    assert any("cabinet holds CDRA-F-0012, locked" in line for line in verified), output[-30:]
    assert any("dirty filter CDRA-F-0007 seated in rack/slot_3" in line for line in verified), output[-30:]
    reports = [
        line.split("report: ", 1)[1] for line in output if "report: " in line and line.strip().startswith("report:")
    ]
    assert any(r.endswith(".html") and Path(r).is_file() for r in reports), output[-10:]


def test_eva_inspection(tmp_path: Path, ros_env: dict[str, str]) -> None:
    output = _demo("eva", tmp_path, ros_env)
    verified = [line for line in output if "verified:" in line]
    for target in ("hull_a", "hull_b", "hull_c", "hull_d"):
        assert any(f"verified: {target}:" in line for line in verified), (target, output[-30:])
