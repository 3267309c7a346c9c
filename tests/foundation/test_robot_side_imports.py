"""Who may import whom, for the parts this layer joins: read from the source, not from a run.

- ``datafile`` is a leaf: it imports no Caretaker package, so both sides can use it.
- The robot side (``at_ros``, ``sim``) never imports the procedure side (``pride``) nor the
  launcher (``caretaker``); ``at_ros`` never imports ``sim`` (the planner gets its world over ROS).
- The procedure side never imports the robot side.
- ``caretaker.stack`` does not import ``caretaker.demo`` (demo builds on the stack, not the reverse).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
PACKAGES = {"datafile": REPO / "python" / "datafile", "at_ros": REPO / "python" / "at_ros", "sim": REPO / "sim",
            "pride": REPO / "python" / "pride", "caretaker": REPO / "python" / "caretaker"}
CARETAKER_PACKAGES = {"datafile", "at_ros", "sim", "pride", "bridge", "caretaker"}


def _imports(path: Path) -> set[str]:
    """Every module name ``path`` imports, wherever in the file (lazy imports count)."""
    names: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            names.add(node.module)
    return names


def _imported_packages(package: str) -> dict[str, set[str]]:
    """Caretaker packages each module of ``package`` imports (other than itself)."""
    out = {}
    for path in sorted(PACKAGES[package].rglob("*.py")):
        used = {name.split(".")[0] for name in _imports(path)} & CARETAKER_PACKAGES - {package}
        if used:
            out[str(path.relative_to(REPO))] = used
    return out


@pytest.mark.parametrize(("package", "forbidden"), [
    ("datafile", CARETAKER_PACKAGES - {"datafile"}),
    ("at_ros", {"sim", "pride", "caretaker", "bridge"}),
    ("sim", {"at_ros", "pride", "caretaker", "bridge"}),
    ("pride", {"at_ros", "sim"}),
])
def test_a_package_imports_only_what_its_side_may(package: str, forbidden: set[str]) -> None:
    offending = {module: used & forbidden for module, used in _imported_packages(package).items() if used & forbidden}
    assert not offending, offending


def test_the_stack_does_not_import_the_demo() -> None:
    assert not any(name.startswith("caretaker.demo") for name in _imports(PACKAGES["caretaker"] / "stack.py"))
