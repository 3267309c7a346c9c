"""The paper's two demonstrations complete end to end, and the world ends as the procedure says.

Each runs ``caretaker demo`` exactly as the README tells a newcomer (simulation as fast as
possible): separate processes for the simulation, planner, AT server, rosbridge and the
procedure runner with its JVM. ``caretaker demo`` exits 0 only if the procedure completed AND
its own checks of the world hold (the deployment's ``demo.checks``, measured by the simulation),
so these tests also read what it verified: one line per check. The undisplaced runs are the
shipped procedures' autonomous runs: their audit log must show every nominal step completed and
the report every step reached.

The EVA inspection also runs on displaced worlds (``--displace SEED``: each hull target moved by
up to 4 cm and 8 degrees, told to nobody but the simulator): the procedure locates each target
from its markers and registers the template there, and what perception found is compared with
where the seed put the target.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from at_ros.transforms import angle_between, from_xyz_quat, from_xyz_rpy
from caretaker.processes import REPO
from pride.audit_log import AuditLog
from pride.events import Event, EventKind
from pride.parser import load_procedure
from sim.displacement import displaced_scene
from sim.scene import load_scene
from support.processes import caretaker

pytestmark = [pytest.mark.ros, pytest.mark.slow(seconds=120)]


def _demo(scenario: str, tmp_path: Path, env: dict[str, str], *more: str) -> list[str]:
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
        *more,
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


def _events(tmp_path: Path) -> list[Event]:
    log = AuditLog(f"sqlite:///{tmp_path / 'audit.db'}")
    try:
        ((run_id, _, _),) = log.runs()
        return log.events(run_id)
    finally:
        log.close()


def _reports(output: list[str]) -> list[Path]:
    return [Path(line.split("report: ", 1)[1]) for line in output if line.strip().startswith("report: ")]


def _every_step_done_and_reported(procedure_file: str, tmp_path: Path, output: list[str]) -> str:
    """The run's audit log has every nominal step's instructions completed, every plan check valid
    and every command but a plan succeeded; the report shows each nominal step reached. Its markdown."""
    events = _events(tmp_path)
    assert events[-1].kind is EventKind.RUN_COMPLETED
    nominal = [s for s in load_procedure(REPO / "procedures" / procedure_file).steps if not s.contingency]
    completed = {e.instruction for e in events if e.kind is EventKind.INSTRUCTION_COMPLETED}
    for step in nominal:
        assert {i.number for i in step.instructions} <= completed, f"step {step.number} not completed"
    plan_checks = [e for e in events if e.kind is EventKind.TELEMETRY_SEEN and e.data["item"] == "plan_valid"]
    assert plan_checks and all(e.data["value"] is True for e in plan_checks if e.data["ok"])
    failed = [
        e.data
        for e in events
        if e.kind is EventKind.COMMAND_RESULT and e.data["command"] != "plan_trajectory" and not e.data["success"]
    ]
    assert not failed, failed  # a failed plan may only have branched
    reports = _reports(output)
    assert any(r.suffix == ".html" and r.is_file() for r in reports), output[-10:]
    markdown = next(r for r in reports if r.suffix == ".md").read_text()
    for step in nominal:
        row = next(line for line in markdown.splitlines() if line.startswith(f"| {step.number} | {step.title} |"))
        assert "not reached" not in row
    return markdown


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
    _every_step_done_and_reported("iva_cdra_filter_replacement.xml", tmp_path, output)


def test_eva_inspection(tmp_path: Path, ros_env: dict[str, str]) -> None:
    output = _demo("eva", tmp_path, ros_env)
    verified = [line.strip() for line in output if "verified:" in line]
    assert verified == ["verified: images of hull_a, hull_b, hull_c, hull_d captured (4 non-empty files)"], output[-30:]
    markdown = _every_step_done_and_reported("eva_inspection.xml", tmp_path, output)
    captured = re.findall(r"!\[[^\]]*(hull_[a-d])[^\]]*\]\(([^)]+)\)", markdown)
    assert sorted(target for target, _ in captured) == ["hull_a", "hull_b", "hull_c", "hull_d"]
    for _, image in captured:  # copied next to the report, real PNGs
        assert (tmp_path / "reports" / image).read_bytes().startswith(b"\x89PNG")


@pytest.mark.parametrize("seed", [3, 17, 42])
def test_eva_inspection_of_a_displaced_hull_registers_each_target_where_the_camera_finds_it(
    seed: int, tmp_path: Path, ros_env: dict[str, str]
) -> None:
    output = _demo("eva", tmp_path, ros_env, "--displace", str(seed))
    verified = [line.strip() for line in output if "verified:" in line]
    assert verified == ["verified: images of hull_a, hull_b, hull_c, hull_d captured (4 non-empty files)"], output[-30:]

    nominal = load_scene(REPO / "sim" / "scenes" / "eva.yaml")
    truth = {t.name: t.pose for t in displaced_scene(nominal, seed).targets}
    events = _events(tmp_path)
    located = {
        e.data["args"]["object"]: e.data["values"]
        for e in events
        if e.kind is EventKind.COMMAND_RESULT and e.data["command"] == "locate" and e.data["success"]
    }
    registered = [
        e.data["args"]
        for e in events
        if e.kind is EventKind.COMMAND_RESULT and e.data["command"] == "set_display_object_pose" and e.data["success"]
    ]
    assert sorted(located) == [f"target/hull_{c}" for c in "abcd"]
    for target in nominal.targets:
        drawn = from_xyz_rpy(target.pose.xyz, target.pose.rpy)
        offset = np.linalg.inv(drawn) @ from_xyz_rpy(truth[target.name].xyz, truth[target.name].rpy)
        v = located[f"target/{target.name}"]
        found = from_xyz_quat([v["x"], v["y"], v["z"]], [v["qx"], v["qy"], v["qz"], v["qw"]])
        mm = float(np.linalg.norm(found[:3, 3] - offset[:3, 3]) * 1000)
        deg = float(np.degrees(angle_between(found, offset)))
        # from where the drawings put the target, so up to 8 degrees off its axis: the accuracy
        # bar of a square view (5 mm, 1 degree at 1 m) is tests/perception's; this is the demo's
        assert mm <= 5.0 and deg <= 2.0, f"{target.name}: located {mm:.1f} mm and {deg:.2f} deg from where it is"
        # the template is registered where the camera found the target, in the drawings' frame
        last = [a for a in registered if a["frame"] == f"target/{target.name}"][-1]
        assert [float(last[k]) for k in ("x", "y", "z", "roll", "pitch", "yaw")] == pytest.approx(
            [v[k] for k in ("x", "y", "z", "roll", "pitch", "yaw")]
        )
