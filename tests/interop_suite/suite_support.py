"""Running ``caretaker interop`` as a user would (a process of its own) and reading its report."""

from __future__ import annotations

import json
import subprocess
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from caretaker.processes import VENV_BIN
from interop.catalog import ALL_CASES

OUTCOMES = {"OK", "NON-STRICT", "INFORMATIONAL", "UNIMPLEMENTED", "FAILED"}


@dataclass(frozen=True)
class SuiteRun:
    """One finished run: its exit code, console output and the report it wrote for ``server``."""

    returncode: int
    output: str
    report: dict[str, dict[str, Any]]
    server: str

    @property
    def cases(self) -> dict[str, Any]:
        return self.report[self.server]

    def outcomes(self) -> dict[str, str]:
        return {case: result["outcome"] for case, result in self.cases.items()}

    def failed(self) -> set[str]:
        return {case for case, outcome in self.outcomes().items() if outcome == "FAILED"}


def start_suite(
    url: str, report: Path, name: str, *options: str, env: dict[str, str], prefix: Sequence[str] = ()
) -> subprocess.Popen[str]:
    """``caretaker interop URL --report DIR --name NAME OPTIONS`` (``prefix``: e.g. ``ip netns exec NS``)."""
    argv = [*prefix, str(VENV_BIN / "caretaker"), "interop", url, "--report", str(report), "--name", name, *options]
    return subprocess.Popen(argv, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


def finish_suite(process: subprocess.Popen[str], report: Path, name: str, timeout: float) -> SuiteRun:
    output, _ = process.communicate(timeout=timeout)
    index = json.loads((report / "index.json").read_text()) if (report / "index.json").exists() else {}
    assert name in index, f"no report of {name} (exit {process.returncode}):\n{output[-3000:]}"
    return SuiteRun(process.returncode, output, index, name)


def citing(statement: str, profiles: Sequence[str]) -> set[str]:
    """The cases of ``profiles`` that cite ``statement``."""
    return {case.number for case in ALL_CASES if statement in case.statements and case.profile in profiles}


def assert_complete(run: SuiteRun, profiles: Sequence[str]) -> None:
    """Every case of ``profiles`` has an outcome, an observation and frames; the HTML links each."""
    wanted = {case.number for case in ALL_CASES if case.profile in profiles}
    assert set(run.cases) == wanted, f"cases missing from the report: {wanted - set(run.cases)}"
    for case, result in run.cases.items():
        assert result["outcome"] in OUTCOMES, (case, result["outcome"])
        assert result["observed"], case
        assert result["frames"], f"{case} has no frames"
        assert {"direction", "at", "text", "connection"} <= set(result["frames"][0]), case
