"""Fuzzing every loader of files from outside: random bytes and mutated shipped files.

Each loader is a :class:`loader_fuzz.Loader`; add a loader by adding one to ``LOADERS``.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from loader_fuzz import Loader, fuzz_mutations, fuzz_random_bytes

from procedure_language.lint import lint_file
from procedure_language.sysrep import load_sysrep_dir

REPO = Path(__file__).resolve().parents[2]
SYSREPS = load_sysrep_dir(REPO / "sysrep")


def _lint(path: Path) -> list[object]:
    return list(lint_file(path, SYSREPS))


LOADERS = [
    Loader("procedure", _lint, suffix=".xml", seeds=tuple(sorted((REPO / "procedures").glob("*.xml")))),
]


@pytest.mark.parametrize("loader", LOADERS, ids=lambda loader: loader.name)
def test_random_bytes_give_problem_lines_or_a_clean_pass(loader: Loader) -> None:
    fuzz_random_bytes(loader)


@pytest.mark.parametrize("loader", LOADERS, ids=lambda loader: loader.name)
def test_mutated_shipped_files_give_problem_lines_or_a_clean_pass(loader: Loader) -> None:
    fuzz_mutations(loader)
