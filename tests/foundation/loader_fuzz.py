"""A reusable fuzz harness for every loader of a file from outside (procedures, SysReps, bindings, ...).

The contract each loader must keep, for any bytes at all: it passes cleanly, or it reports
problems as single lines ``file:line[:col]: message``; it never raises anything else (which
would reach the user as a traceback) and never takes more than :data:`DEADLINE_MS` on one input
(hypothesis's per-example deadline measures that, so a slow input fails with its bytes shown).

To fuzz a loader, describe it with :class:`Loader` and call :func:`fuzz_random_bytes` and
:func:`fuzz_mutations` from a test (see test_fuzz_loaders.py).
"""

from __future__ import annotations

import re
import shutil
import tempfile
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

__all__ = ["DEADLINE_MS", "Loader", "check_one", "fuzz_mutations", "fuzz_random_bytes", "mutated"]

#: The most one input may take, in milliseconds.
DEADLINE_MS = 5000

_PROBLEM_LINE = re.compile(r"[^\n]+:\d+(?::\d+)?: [^\n]+")

#: Fragments that hit the interesting corners of XML and YAML parsers when spliced into a file.
TOKENS: tuple[bytes, ...] = (
    b'<!DOCTYPE p [<!ENTITY a "aaaaaaaaaa"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;">]>',
    b"&a;",
    b"&nbsp;",
    b"&#0;",
    b'<!DOCTYPE p SYSTEM "http://127.0.0.1:9/x.dtd">',
    b"</step>",
    b'<step title="x">',
    b"<step>" * 200,
    b"]]>",
    b"<![CDATA[",
    b"<!--",
    b"-->",
    b'<?xml version="1.0" encoding="latin1"?>',
    b"\xff\xfe",
    b"\x00",
    b"\xc3",
    b'="',
    b"'",
    b"<",
    b">",
    b"/>",
    b"${",
    b"${x.y}",
    b"\n",
    b"\t",
    b" " * 50,
    b"&x:",
    b"*x",
    b"!!python/object:os.system",
    b"- [",
    b"]]",
    b"{{",
    b": : :",
    b"? ",
    b"---\n",
    b"1e999999",
    b"nan",
    b".inf",
    b"-9999999999999999999999999",
    b'"\\u0000"',
    b"|\n",
    b">-\n",
)


@dataclass(frozen=True)
class Loader:
    """A file loader under test.

    Args:
        name: what it loads, for test ids.
        load: reads one file; returns the problems found (empty for a clean pass).
        errors: exception types it raises for a bad file, each carrying one problem in ``str()``.
        suffix: the file name ending it expects (``.xml``, ``.yaml``).
        seeds: real files to mutate (the shipped ones); files beside a seed are copied along, so
            references between files (a procedure calling a sub-procedure) still resolve.
    """

    name: str
    load: Callable[[Path], Sequence[object]]
    errors: tuple[type[Exception], ...] = ()
    suffix: str = ".xml"
    seeds: tuple[Path, ...] = ()


def check_one(loader: Loader, path: Path) -> list[str]:
    """Load one file and check the contract; return the problem lines (empty: a clean pass)."""
    try:
        problems = [str(p) for p in loader.load(path)]
    except loader.errors as exc:
        problems = [str(exc)]
    for line in problems:
        assert _PROBLEM_LINE.fullmatch(line), f"{loader.name}: not one problem line: {line!r}"
    return problems


@st.composite
def mutated(draw: st.DrawFn, seeds: Sequence[bytes]) -> bytes:
    """A seed file with a few random cuts, copies, splices of tokens or random bytes, and byte flips."""
    data = bytearray(draw(st.sampled_from(seeds)))
    for _ in range(draw(st.integers(1, 4))):
        at = draw(st.integers(0, len(data)))
        kind = draw(st.sampled_from(("cut", "copy", "token", "bytes", "flip")))
        if kind == "cut":
            del data[at : at + draw(st.integers(1, 200))]
        elif kind == "copy":
            start = draw(st.integers(0, len(data)))
            data[at:at] = data[start : start + draw(st.integers(1, 400))]
        elif kind == "token":
            data[at:at] = draw(st.sampled_from(TOKENS))
        elif kind == "bytes":
            data[at:at] = draw(st.binary(min_size=1, max_size=16))
        elif data:
            index = min(at, len(data) - 1)
            data[index] = draw(st.integers(0, 255))
    return bytes(data)


def _workspace(loader: Loader) -> Path:
    """A temporary folder holding copies of the seeds' folders (removed by the caller)."""
    root = Path(tempfile.mkdtemp(prefix=f"caretaker-fuzz-{loader.name}-"))
    for folder in {seed.parent for seed in loader.seeds}:
        for sibling in folder.iterdir():
            if sibling.is_file():
                shutil.copy2(sibling, root / sibling.name)
    return root


def _run(loader: Loader, strategy: st.SearchStrategy[bytes], examples: int) -> None:
    root = _workspace(loader)
    target = root / f"fuzzed{loader.suffix}"

    @settings(
        max_examples=examples,
        deadline=DEADLINE_MS,
        derandomize=False,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    @given(strategy)
    def one(data: bytes) -> None:
        target.write_bytes(data)
        check_one(loader, target)

    try:
        one()
    finally:
        shutil.rmtree(root, ignore_errors=True)


def fuzz_random_bytes(loader: Loader, *, examples: int = 200) -> None:
    """Random bytes (and random text) fed to the loader: always a clean pass or problem lines."""
    _run(loader, st.binary(max_size=4096) | st.text(max_size=2048).map(str.encode), examples)


def fuzz_mutations(loader: Loader, *, examples: int = 300) -> None:
    """The loader's seed files, mutated: always a clean pass or problem lines."""
    seeds = [seed.read_bytes() for seed in loader.seeds]
    assert seeds, f"{loader.name}: no seed files to mutate"
    _run(loader, mutated(seeds), examples)
