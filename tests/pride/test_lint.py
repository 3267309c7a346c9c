"""`caretaker lint`: broken procedures fail with the right file:line:col and message; good ones pass."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from procedure_language.lint import lint_file
from procedure_language.sysrep import SysRep
from support.procedures import FIXTURES, REPO
from support.processes import COMMAND_HANG_S

BROKEN = FIXTURES / "broken"
EXPECTED: dict[str, list[str]] = yaml.safe_load((BROKEN / "expected_errors.yaml").read_text())
SHIPPED = sorted((REPO / "procedures").glob("*.xml"))


def test_every_broken_fixture_has_expectations() -> None:
    assert sorted(EXPECTED) == sorted(p.name for p in BROKEN.glob("*.xml"))


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_broken_procedure_reports_each_error_where_it_is(name: str, sysreps: dict[str, SysRep]) -> None:
    path = BROKEN / name
    printed = [str(p) for p in lint_file(path, sysreps)]
    assert len(printed) == len(EXPECTED[name]), printed
    for line, expected in zip(printed, EXPECTED[name], strict=True):
        position, _, text = expected.partition(": ")
        assert line.startswith(f"{path}:{position}: "), (line, expected)
        assert text in line, (line, expected)


@pytest.mark.parametrize("path", SHIPPED, ids=lambda p: p.name)
def test_shipped_procedures_are_clean(path: Path, sysreps: dict[str, SysRep]) -> None:
    assert lint_file(path, sysreps) == []


def test_lab_procedures_are_clean(sysreps: dict[str, SysRep]) -> None:
    for name in ("lab_all_kinds.xml", "lab_outputs.xml"):
        assert lint_file(FIXTURES / name, sysreps) == [], name


def test_cli_prints_errors_and_exits_nonzero() -> None:
    broken = [str(BROKEN / "unknown_command.xml"), str(BROKEN / "goto_nowhere.xml")]
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "caretaker.cli",
            "lint",
            *broken,
            "--sysrep-dir",
            str(REPO / "sysrep"),
            "--sysrep-dir",
            str(FIXTURES / "sysrep"),
        ],
        capture_output=True,
        text=True,
        timeout=COMMAND_HANG_S,
    )
    assert proc.returncode == 1
    lines = proc.stdout.splitlines()
    assert f"{broken[0]}:5:27: unknown command 'mvoe' in lab (commands: move, vent, capture, count)" in lines
    assert any(line.startswith(f"{broken[1]}:6:11: go-to to nowhere") for line in lines)
    assert "2 of 2 procedure(s) have errors" in proc.stderr


def test_cli_passes_the_shipped_procedures() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "lint", *map(str, SHIPPED)], capture_output=True, text=True, timeout=60
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    # one line per file, saying what was checked
    assert [
        line.split(": ok (schema, and every command and telemetry name against ")[0]
        for line in proc.stdout.splitlines()
    ] == [str(p) for p in SHIPPED], proc.stdout
