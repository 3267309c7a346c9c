"""Sizes that stay small: a module a newcomer can read through, a package one can hold in mind.

No Python module over 650 lines, no console JS module over 700, no package directly under
``python/`` over 8,000 lines of Python, counted as ``wc -l`` counts them (newlines). The files
counted are those a commit would hold (``git ls-files``: tracked, and new files not ignored), so
a generated bundle such as the 3D view's ``static/spatial.js`` (built by ``make setup`` from
``console/spatial/src``, whose modules are counted) is not. A failure names every file or
package over its limit, so growth shows the day it happens and is split by concept then.
"""

from __future__ import annotations

import subprocess
from collections import Counter
from pathlib import Path

from caretaker.processes import REPO

MODULE_LINES = 650
JS_MODULE_LINES = 700
PACKAGE_LINES = 8000


def files(*patterns: str) -> list[Path]:
    """The files a commit would hold under ``patterns`` (git pathspecs)."""
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", "--", *patterns],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.splitlines()
    return [REPO / name for name in listed if (REPO / name).is_file()]


def lines(path: Path) -> int:
    """What ``wc -l`` says: the number of newline characters."""
    return path.read_bytes().count(b"\n")


def over(paths: list[Path], limit: int) -> list[str]:
    return [f"{path.relative_to(REPO)}: {n} lines" for path in paths if (n := lines(path)) > limit]


def test_no_python_module_is_over_650_lines() -> None:
    modules = files("python/*.py", "sim/*.py", "bench/*.py", "tools/*.py")
    assert len(modules) > 100, "the listing found too few modules to be what it claims"
    found = over(modules, MODULE_LINES)
    assert not found, f"modules over {MODULE_LINES} lines (split them by concept): " + "; ".join(found)


def test_no_console_js_module_is_over_700_lines() -> None:
    scripts = files("python/console/*.js")
    assert any(p.name == "run_view.js" for p in scripts), "the listing found no console script"
    found = over(scripts, JS_MODULE_LINES)
    assert not found, f"console JS modules over {JS_MODULE_LINES} lines (split them by concept): " + "; ".join(found)


def test_no_package_under_python_is_over_8000_lines() -> None:
    totals: Counter[str] = Counter()
    for path in files("python/*.py"):
        totals[path.relative_to(REPO / "python").parts[0]] += lines(path)
    assert {"pride", "console", "records"} <= set(totals)
    found = [f"python/{package}: {n} lines" for package, n in sorted(totals.items()) if n > PACKAGE_LINES]
    assert not found, f"packages over {PACKAGE_LINES} lines (move a concept out): " + "; ".join(found)


def test_the_count_is_wc_l(tmp_path: Path) -> None:
    sample = tmp_path / "sample.py"
    sample.write_text("one\ntwo\nthree without a newline")
    assert lines(sample) == 2  # as `wc -l sample.py` prints
    assert over([REPO / "pyproject.toml"], 1) and not over([REPO / "pyproject.toml"], 10**6)
