"""What the ground learns of a robot side from its deployment: a simulator? which commands need a
second operator's approval? And which procedures may therefore not run onboard."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from datafile import DataFileError
from pride.approvals import ApprovalPolicy, CriticalLevel, approval_points, missing_approvals_text
from pride.gateways import GATEWAY_ENV
from pride.robot_sides import robot_side_for
from procedure_language.lint import check_procedure
from procedure_language.sysrep import SysRep
from support.procedures import FIXTURES, REPO

BINDINGS = REPO / "sysrep" / "bindings"


def _robot_folder(tmp_path: Path, deployment_extra: str) -> Path:
    """A robot folder as `caretaker new robot` writes one: its binding beside its deployment."""
    folder = tmp_path / "robot"
    folder.mkdir()
    shutil.copy(BINDINGS / "iva.yaml", folder / "binding.yaml")
    (folder / "deployment.yaml").write_text(
        f"name: bench\nscene: iva\nrobot: ur10\ntemplates: .\nbindings: [binding.yaml]\n{deployment_extra}"
    )
    return folder


def test_a_binding_finds_the_deployment_that_serves_it(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(GATEWAY_ENV, raising=False)
    shipped = robot_side_for(BINDINGS / "iva-ground.yaml")
    assert shipped.deployment == REPO / "deployments" / "iva-habitat.yaml" and shipped.simulator
    assert shipped.approvals.level is CriticalLevel.HAZARDOUS

    beside = robot_side_for(
        _robot_folder(tmp_path, "critical_commanding: {level: all, approval_expires_s: 60}\n") / "binding.yaml"
    )
    assert beside.deployment == tmp_path / "robot" / "deployment.yaml"
    assert (beside.simulator, beside.approvals.level, beside.approvals.expires_s) == (False, CriticalLevel.ALL, 60.0)
    assert beside.rehearsal_refusal() == (
        f"a rehearsal runs only against a simulator, and {beside.deployment} is not one (no simulator: true)"
    )

    nobody = tmp_path / "loose.yaml"
    shutil.copy(BINDINGS / "iva.yaml", nobody)
    alone = robot_side_for(nobody)
    assert alone.deployment is None and not alone.simulator
    assert alone.approvals.level is CriticalLevel.HAZARDOUS  # nobody described it: the safe default
    assert "no deployment serves" in (alone.rehearsal_refusal() or "")

    monkeypatch.setenv(GATEWAY_ENV, "lab_gateway:open_lab")  # a stand-in in the runner's process: no robot
    assert robot_side_for(nobody).simulator


def test_a_wrong_level_is_refused_at_its_line(tmp_path: Path) -> None:
    folder = _robot_folder(tmp_path, "simulator: true\ncritical_commanding: {level: sometimes}\n")
    with pytest.raises(DataFileError, match=r"deployment.yaml:7: critical_commanding.level: unknown value 'sometimes'"):
        robot_side_for(folder / "binding.yaml")


def test_off_is_the_yaml_word_too(tmp_path: Path) -> None:
    folder = _robot_folder(tmp_path, "critical_commanding: off\n")
    assert robot_side_for(folder / "binding.yaml").approvals.level is CriticalLevel.OFF


def test_the_commands_an_onboard_unit_must_carry_approved_are_named_where_they_are(sysreps: dict[str, SysRep]) -> None:
    checked = check_procedure(FIXTURES / "lab_all_kinds.xml", sysreps)
    main = (FIXTURES / "lab_all_kinds.xml").resolve()
    hazardous = ApprovalPolicy(CriticalLevel.HAZARDOUS)
    points = approval_points(checked, hazardous)
    assert [point.describe(main) for point in points] == ["2.1 lab.vent"]
    assert missing_approvals_text(points, main, hazardous) == (
        "2.1 lab.vent needs a second operator's approval (hazardous commands need a second operator's approval "
        "(good for 300 s))"
    )
    assert approval_points(checked, ApprovalPolicy(CriticalLevel.OFF)) == []
    every = [point.describe(main) for point in approval_points(checked, ApprovalPolicy(CriticalLevel.ALL))]
    assert every[:3] == ["1.3 lab.move", "2.1 lab.vent", "2.3 lab.capture"]
    assert any(described.endswith(" in lab_sub.xml") and "count" in described for described in every)
