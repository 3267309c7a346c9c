"""A robot in an afternoon (issue 30): ``caretaker new robot`` on a URDF, then its demo, outside the checkout.

pybullet's KUKA iiwa (no shipped file uses it) becomes a folder in a temporary directory;
``caretaker check`` accepts every file in it; ``caretaker demo`` on its deployment starts the
real robot side (simulation, planner with OMPL, AT server, ledger, rosbridge), runs the survey
procedure through the Java PAX plugins, and its world checks — the tool at each survey pose, as
the simulation measured it — pass. The audit log and the report land in the robot's folder,
and nothing in the checkout changed.
"""

from __future__ import annotations

import re
from pathlib import Path

import pybullet_data
import pytest

from caretaker.processes import REPO
from support.checkout import checkout_status
from support.processes import caretaker

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=25)]

IIWA = Path(pybullet_data.getDataPath()) / "kuka_iiwa" / "model.urdf"
VERIFIED = re.compile(
    r"^verified: lbr_iiwa_link_7 reached \(-?\d+, -?\d+, -?\d+\) mm in robot_base: (\d+) mm, (\d+\.\d)° from it "
    r"\(within 5 mm, 2°\)$"
)


def _finished(*args: str, env: dict[str, str], timeout: float) -> list[str]:
    """Run ``caretaker ARGS`` to its end; its output (it must exit 0)."""
    proc = caretaker(*args, env=env, name=args[0])
    try:
        proc.proc.wait(timeout=timeout)
    finally:
        proc.stop()
    output = list(proc.output)
    assert proc.proc.returncode == 0, "\n".join(output[-60:])
    return output


def test_a_robot_made_from_a_urdf_runs_its_demo_outside_the_checkout(tmp_path: Path, ros_env: dict[str, str]) -> None:
    before = checkout_status()
    folder = tmp_path / "iiwa"
    assert REPO not in folder.resolve().parents
    _finished("new", "robot", "iiwa", "--urdf", str(IIWA), "--into", str(folder), env=ros_env, timeout=120)
    files = sorted(p for p in folder.rglob("*") if p.is_file())
    checked = _finished("check", *map(str, files), env=ros_env, timeout=120)
    assert [line for line in checked if ": ok (" in line] == [
        f"{p}: ok ({kind})"
        for p, kind in zip(
            files,
            (
                "a binding",
                "a deployment",
                "a robot config",
                "a scene",
                "a procedure, linted against the shipped SysReps",
                "an AT template",
            ),
            strict=True,
        )
    ]

    # As a user runs it: the defaults, and a free port (tests run side by side)
    output = _finished("demo", str(folder / "deployment.yaml"), "--bridge-port", "0", env=ros_env, timeout=420)
    verified = [line.strip() for line in output if "verified:" in line]
    assert len(verified) == 3, output[-30:]
    for line in verified:
        measured = VERIFIED.match(line)
        assert measured, line
        assert int(measured[1]) <= 5 and float(measured[2]) <= 2.0
    run = next(line.split()[-1] for line in output if " demo complete; run " in line)
    # The audit log and report in the robot's own folder, not the checkout's var/
    assert f"  audit log: sqlite:///{folder / 'var' / 'caretaker.db'}" in output
    assert (folder / "var" / "reports" / f"{run}.html").is_file()
    assert not (REPO / "var" / "reports" / f"{run}.html").exists()
    assert checkout_status() == before
