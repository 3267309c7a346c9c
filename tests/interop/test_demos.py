"""The paper's two demonstrations complete end to end, and the world ends as the procedure says.

Each runs ``caretaker demo`` exactly as the README tells a newcomer (simulation as fast as
possible): separate processes for the simulation, planner, AT server, rosbridge and the
procedure runner with its JVM. ``caretaker demo`` exits 0 only if the procedure completed AND
its own checks of the world hold (the deployment's ``demo.checks``, measured by the simulation),
so these tests also read what it verified: one line per check.
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
    verified = [line.strip() for line in output if "verified:" in line]
    assert len(verified) == 3, output[-30:]
    assert verified[0].startswith("verified: filter/CDRA-F-0007 is at rack/slot_3: "), verified
    assert verified[0].endswith(" mm from it (within 30 mm)"), verified
    assert verified[1:] == [
        "verified: /cdra/installed_filter_id is 'CDRA-F-0012'",
        "verified: /cdra/filter_locked is True",
    ]
    reports = [
        line.split("report: ", 1)[1] for line in output if "report: " in line and line.strip().startswith("report:")
    ]
    assert any(r.endswith(".html") and Path(r).is_file() for r in reports), output[-10:]


def test_eva_inspection(tmp_path: Path, ros_env: dict[str, str]) -> None:
    output = _demo("eva", tmp_path, ros_env)
    verified = [line.strip() for line in output if "verified:" in line]
    assert verified == ["verified: images of hull_a, hull_b, hull_c, hull_d captured (4 non-empty files)"], output[-30:]
