"""Hostile and damaged procedure files: one line per problem at the exact file:line:col, never a traceback.

A DOCTYPE (and so any entity, internal or external) is refused before the XML parser sees it:
nothing is read from a file or the network, nothing is expanded. The expectations are in
``fixtures/hostile/expected_errors.yaml``; a few cases also run ``caretaker lint`` as a process.
"""

from __future__ import annotations

import socket
import subprocess
import sys
import threading
from pathlib import Path

import pytest
import yaml

from procedure_language.lint import lint_file
from procedure_language.sysrep import SysRep, load_sysrep_dir
from support.procedures import FIXTURES

HOSTILE = FIXTURES / "hostile"
EXPECTED: dict[str, list[str]] = yaml.safe_load((HOSTILE / "expected_errors.yaml").read_text())
LAB_SYSREPS = FIXTURES / "sysrep"


@pytest.fixture(scope="module")
def lab() -> dict[str, SysRep]:
    return load_sysrep_dir(LAB_SYSREPS)


def caretaker_lint(*paths: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "lint", "--sysrep-dir", str(LAB_SYSREPS), *map(str, paths)],
        capture_output=True,
        text=True,
        timeout=120,
    )


def test_every_hostile_fixture_has_expectations() -> None:
    assert sorted(EXPECTED) == sorted(p.name for p in HOSTILE.glob("*.xml"))


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_lint_names_the_exact_place_and_what_to_do(name: str, lab: dict[str, SysRep]) -> None:
    path = HOSTILE / name
    assert [str(p) for p in lint_file(path, lab)] == [f"{path}:{line}" for line in EXPECTED[name]]


def clean(path: Path) -> str:
    """What lint says of a clean file: what it checked it against (the lab's one SysRep)."""
    return f"{path}: ok (schema, and every command and telemetry name against 1 SysRep)"


def test_caretaker_lint_prints_one_line_per_problem_and_no_traceback() -> None:
    paths = [HOSTILE / name for name in sorted(EXPECTED)]
    run = caretaker_lint(*paths)
    assert "Traceback" not in run.stdout + run.stderr
    assert run.returncode == 1
    assert run.stdout.splitlines() == [
        line
        for name in sorted(EXPECTED)
        for line in ([f"{HOSTILE / name}:{line}" for line in EXPECTED[name]] or [clean(HOSTILE / name)])
    ]
    failing = sum(1 for name in EXPECTED if EXPECTED[name])
    assert run.stderr.strip() == f"{failing} of {len(paths)} procedure(s) have errors"


def test_a_clean_file_that_mentions_doctype_in_a_comment_passes() -> None:
    run = caretaker_lint(HOSTILE / "doctype_in_comment.xml")
    assert (run.returncode, run.stdout, run.stderr) == (0, clean(HOSTILE / "doctype_in_comment.xml") + "\n", "")


def test_an_external_entity_is_never_read_nor_fetched(tmp_path: Path, lab: dict[str, SysRep]) -> None:
    secret = tmp_path / "secret.txt"
    secret.write_text("TOP-SECRET-MARKER")
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen()
    listener.settimeout(0.2)
    port = listener.getsockname()[1]
    connections: list[object] = []
    stop = threading.Event()

    def accept() -> None:
        while not stop.is_set():
            try:
                connections.append(listener.accept()[0])
            except TimeoutError:
                continue

    thread = threading.Thread(target=accept, daemon=True)
    thread.start()
    path = tmp_path / "leak.xml"
    path.write_text(
        f'<?xml version="1.0"?>\n<!DOCTYPE procedure SYSTEM "http://127.0.0.1:{port}/p.dtd" [\n'
        f'  <!ENTITY leak SYSTEM "file://{secret}">\n'
        f'  <!ENTITY remote SYSTEM "http://127.0.0.1:{port}/e">\n]>\n'
        '<procedure id="p" title="&leak;&remote;" version="1">\n'
        '  <step title="One"><manual>&leak;</manual></step>\n</procedure>\n'
    )
    try:
        printed = [str(p) for p in lint_file(path, lab)]
        run = caretaker_lint(path)
    finally:
        stop.set()
        thread.join()
        listener.close()
    assert printed == [
        f"{path}:2:1: <!DOCTYPE ...> is not allowed in a procedure (no DTD, no entities, nothing is "
        "read from elsewhere): remove it"
    ]
    assert run.stdout.splitlines() == printed and "Traceback" not in run.stderr
    assert "TOP-SECRET-MARKER" not in run.stdout + run.stderr
    assert connections == []
