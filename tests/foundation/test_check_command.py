"""`caretaker check` and `caretaker lint` say what they checked, and a procedure given to check is linted."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

from caretaker.processes import REPO

PROCEDURE = REPO / "procedures" / "iva_cdra_filter_replacement.xml"


def caretaker(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "caretaker.cli", *args], capture_output=True, text=True, timeout=120, check=False
    )


def test_a_procedure_given_to_check_is_linted_one_line_per_problem(tmp_path: Path) -> None:
    broken = tmp_path / "broken.xml"
    text = PROCEDURE.read_text().replace('name="plan_trajectory"', 'name="plan_trajectry"', 1)
    assert text != PROCEDURE.read_text()
    broken.write_text(text)
    shutil.copy(PROCEDURE.parent / "iva_look_locate_register.xml", tmp_path)  # its call resolves next to it
    line = next(n for n, row in enumerate(text.splitlines(), 1) if "plan_trajectry" in row)
    proc = caretaker("check", str(PROCEDURE), str(broken))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0] == f"{PROCEDURE}: ok (a procedure, linted against the shipped SysReps)"
    assert len(lines) == 2 and lines[1].startswith(f"{broken}:{line}:"), lines
    assert "plan_trajectry" in lines[1] and "YAML" not in proc.stdout


def test_lint_says_what_it_checked_when_all_is_well() -> None:
    proc = caretaker("lint", str(PROCEDURE))
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert proc.stdout.startswith(f"{PROCEDURE}: ok (schema, and every command and telemetry name against ")


def test_a_misspelt_link_in_a_scene_is_caught_at_its_line_before_anything_starts(tmp_path: Path) -> None:
    text = (REPO / "sim" / "scenes" / "iva.yaml").read_text()
    text = text.replace("urdf: ../robots/ur10_gripper.urdf", f"urdf: {REPO / 'sim' / 'robots' / 'ur10_gripper.urdf'}")
    scene = tmp_path / "scene.yaml"
    scene.write_text(text.replace("tool_link: tool0", "tool_link: tool00"))
    line = next(n for n, row in enumerate(scene.read_text().splitlines(), 1) if "tool_link: tool00" in row)
    proc = caretaker("check", str(scene))
    assert proc.returncode == 1
    assert proc.stdout.strip().startswith(
        f"{scene}:{line}: robot.tool_link: the URDF ur10_gripper.urdf has no link 'tool00'"
    )


def test_a_broken_urdf_and_a_missing_mesh_are_one_line_each(tmp_path: Path) -> None:
    broken = tmp_path / "broken.urdf"
    broken.write_text('<robot name="r">\n  <link name="base">\n</robot>\n')
    meshless = tmp_path / "meshless.urdf"
    meshless.write_text(
        '<robot name="r">\n  <link name="base">\n    <visual><geometry>\n'
        '      <mesh filename="meshes/base.stl"/>\n    </geometry></visual>\n  </link>\n</robot>\n'
    )
    proc = caretaker("check", str(broken), str(meshless), str(REPO / "sim" / "robots" / "ur10_gripper.urdf"))
    assert proc.returncode == 1 and "Traceback" not in proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[0].startswith(f"{broken}:") and "not valid XML" in lines[0], lines
    assert lines[1].startswith(f"{meshless}:4: mesh file 'meshes/base.stl' not found"), lines
    assert lines[2].endswith("ok (a URDF: it parses and every mesh it names on this host is there)"), lines


def test_an_unknown_frame_in_a_deployments_world_check_is_caught_at_its_line(tmp_path: Path) -> None:
    text = (REPO / "deployments" / "iva.yaml").read_text().replace("../", f"{REPO}/")
    deployment = tmp_path / "iva.yaml"
    deployment.write_text(text.replace("at: rack/slot_3", "at: rack/slot_9"))
    line = next(n for n, row in enumerate(deployment.read_text().splitlines(), 1) if "rack/slot_9" in row)
    proc = caretaker("check", str(deployment))
    assert proc.returncode == 1, proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 1 and lines[0].startswith(f"{deployment}:{line}: demo.checks[0].at: "), lines
    assert "has no frame 'rack/slot_9'" in lines[0] and "Traceback" not in proc.stderr
