"""Shared pieces of the procedure-side tests: SysReps, the lab procedures, the lab gateway."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
FIXTURES = HERE / "fixtures"
sys.path.insert(0, str(HERE))  # lab_gateway is importable here and in runner subprocesses

from pride.sysrep import SysRep, load_sysrep_dir  # noqa: E402


@pytest.fixture(scope="session")
def sysreps() -> dict[str, SysRep]:
    """The repository's SysReps plus the lab bench's."""
    return {**load_sysrep_dir(REPO / "sysrep"), **load_sysrep_dir(FIXTURES / "sysrep")}
