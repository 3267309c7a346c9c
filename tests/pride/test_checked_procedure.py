"""A run checks its procedure tree once and runs exactly what was checked.

``check_procedure`` parses and lints each file once (however often it is called); the executive
then reads no file: a sub-procedure edited on disk after the check does not change the run.
Literal arguments leave typed, so the gateway receives the SysRep's types.
"""

from __future__ import annotations

import shutil
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import pytest

import procedure_language.lint
from pride.executive import Executive, Hold, Mode, RunStatus
from procedure_language.diagnostics import Problem
from procedure_language.lint import check_procedure
from procedure_language.model import Procedure
from procedure_language.parser import parse_procedure
from procedure_language.sysrep import SysRep
from support.audit import RecordedJournal
from support.lab_gateway import LabGateway
from support.procedures import FIXTURES


def test_each_file_is_parsed_once(tmp_path: Path, sysreps: dict[str, SysRep], monkeypatch: pytest.MonkeyPatch) -> None:
    main = tmp_path / "twice.xml"
    main.write_text(
        (FIXTURES / "lab_all_kinds.xml")
        .read_text()
        .replace(
            '<call procedure="lab_sub.xml">',
            '<call procedure="lab_sub.xml"><arg name="count">2</arg></call>\n    <call procedure="lab_sub.xml">',
        )
    )
    shutil.copy(FIXTURES / "lab_sub.xml", tmp_path / "lab_sub.xml")
    parsed: Counter[str] = Counter()

    def counting(path: str | Path) -> tuple[Procedure | None, list[Problem]]:
        parsed[Path(path).name] += 1
        return parse_procedure(path)

    monkeypatch.setattr(procedure_language.lint, "parse_procedure", counting)
    checked = check_procedure(main, sysreps)
    assert parsed == {"twice.xml": 1, "lab_sub.xml": 1}
    assert checked.load(str((tmp_path / "lab_sub.xml").resolve())).id == "lab_sub"


def test_a_run_runs_what_was_checked(
    tmp_path: Path, sysreps: dict[str, SysRep], new_journal: Callable[..., RecordedJournal]
) -> None:
    shutil.copy(FIXTURES / "lab_all_kinds.xml", tmp_path / "main.xml")
    shutil.copy(FIXTURES / "lab_sub.xml", tmp_path / "lab_sub.xml")
    checked = check_procedure(tmp_path / "main.xml", sysreps)
    (tmp_path / "lab_sub.xml").write_text("not a procedure any more")  # edited after the check

    gateway = LabGateway(str(tmp_path / "images"))
    executive = Executive(checked, gateway, new_journal(), run_id="r", mode=Mode.AUTONOMOUS)
    executive.start("ada")
    answers = {
        Hold.OPERATOR_INPUT: lambda: executive.enter("ada", "dock"),
        Hold.CONFIRMATION: lambda: executive.confirm("ada"),
        Hold.OPERATOR_ACTION: lambda: executive.mark_done("ada"),
    }
    while (
        snap := executive.wait_for(lambda s: s.hold is not None or s.status is not RunStatus.ACTIVE, 20)
    ) and snap.status is RunStatus.ACTIVE:
        answers[snap.hold]()
    executive.join(20)
    assert snap is not None and snap.status is RunStatus.COMPLETED, snap
    assert ("lab", "count", {"n": 3}) in gateway.sent  # the checked sub-procedure ran
    assert ("lab", "move", {"target": "dock", "speed": 0.5}) in gateway.sent  # literal 0.5 sent as a real
