"""A run's set-up, shared by the console, ``caretaker run`` and the habitat (:mod:`pride.run_setup`)."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest

from pride.approvals import ApprovalPolicy
from pride.robot_sides import RobotSide
from pride.run_setup import RunSetup, load_sysreps, new_run_id
from pride.run_version import RunVersion
from procedure_language.diagnostics import ProcedureError
from procedure_language.lint import CheckedProcedure
from procedure_language.sysrep import SysRep, SysRepError
from records.audit_log import AuditLog
from support.lab_gateway import LabGateway
from support.procedures import FIXTURES, REPO

LAB = FIXTURES / "lab_all_kinds.xml"


def lab_side(tmp_path: Path) -> RobotSide:
    return RobotSide(tmp_path / "lab.yaml", None, simulator=True, approvals=ApprovalPolicy())


def test_sysrep_folders_load_as_one_and_a_duplicate_id_names_both_files(tmp_path: Path) -> None:
    both = load_sysreps([REPO / "sysrep", FIXTURES / "sysrep"])
    assert "lab" in both and len(both) == len(load_sysreps([REPO / "sysrep"])) + 1
    copy = tmp_path / "copy"
    copy.mkdir()
    shutil.copy(FIXTURES / "sysrep" / "lab.yaml", copy / "lab_again.yaml")
    with pytest.raises(SysRepError) as refused:
        load_sysreps([FIXTURES / "sysrep", copy])
    message = str(refused.value)
    assert "duplicate SysRep id 'lab'" in message
    assert str(copy / "lab_again.yaml") in message and str(FIXTURES / "sysrep" / "lab.yaml") in message


def test_a_new_run_gets_its_id_and_the_version_its_launcher_decides(sysreps: dict[str, SysRep], tmp_path: Path) -> None:
    decided: list[str] = []

    def rule(checked: CheckedProcedure, side: RobotSide) -> RunVersion:
        decided.append(checked.procedure.id)
        return RunVersion("ab" * 32, 3, False)

    side = lab_side(tmp_path)
    setup = RunSetup.prepare(LAB, side, sysreps, version=rule)
    assert decided == [setup.checked.procedure.id]  # decided once
    assert re.fullmatch(rf"{re.escape(setup.checked.procedure.id)}-\d{{8}}T\d{{6}}Z-[0-9a-f]{{4}}", setup.run_id)
    assert setup.version == RunVersion("ab" * 32, 3, False) and setup.side is side
    carried = RunSetup.prepare(LAB, side, sysreps, version=lambda *_: None, run_id="carried-1")
    assert carried.run_id == "carried-1" and carried.version is None
    assert re.fullmatch(r"p-\d{8}T\d{6}Z-[0-9a-f]{4}", new_run_id("p"))


def test_a_procedure_with_errors_or_a_refused_version_sets_up_nothing(
    sysreps: dict[str, SysRep], tmp_path: Path
) -> None:
    broken = tmp_path / "broken.xml"
    broken.write_text(LAB.read_text().replace('system="lab"', 'system="nowhere"', 1))
    with pytest.raises(ProcedureError):
        RunSetup.prepare(broken, lab_side(tmp_path), sysreps)

    def refuse(checked: CheckedProcedure, side: RobotSide) -> RunVersion:
        raise LookupError("a draft")

    with pytest.raises(LookupError, match="a draft"):
        RunSetup.prepare(LAB, lab_side(tmp_path), sysreps, version=refuse)


def test_a_gateway_without_a_system_the_procedure_uses_is_named(sysreps: dict[str, SysRep], tmp_path: Path) -> None:
    setup = RunSetup.prepare(LAB, lab_side(tmp_path), sysreps)
    gateway = LabGateway()
    try:
        assert setup.unserved(gateway) is None
        setup_elsewhere = RunSetup.prepare(
            REPO / "procedures" / "iva_cdra_filter_replacement.xml", lab_side(tmp_path), sysreps
        )
        unserved = setup_elsewhere.unserved(gateway)
        assert unserved is not None and unserved.startswith("binding lab.yaml serves no ")
        assert unserved.endswith("which iva_cdra_filter_replacement.xml uses")
    finally:
        gateway.close()


def test_the_executive_is_built_from_the_setup(sysreps: dict[str, SysRep], tmp_path: Path) -> None:
    setup = RunSetup.prepare(LAB, lab_side(tmp_path), sysreps, version=lambda *_: RunVersion("cd" * 32, None, True))
    gateway = LabGateway()
    journal = AuditLog(f"sqlite:///{tmp_path / 'audit.db'}")
    try:
        executive = setup.executive(gateway, journal, control=None)
        assert executive.run_id == setup.run_id and executive.version == setup.version
        assert executive.procedure is setup.checked.procedure
    finally:
        gateway.close()
        journal.close()
