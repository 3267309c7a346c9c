"""The package graph: the allowed import order, no import cycles; the procedure side never reaches ROS.

Imports are read statically (ast) from every module of every top-level package that pyproject.toml
declares, including imports inside functions: a lazy import is still a dependency. A failure
names the cycle or the chain of imports.
"""

from __future__ import annotations

import ast
import tomllib
from collections.abc import Iterator
from functools import cache
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]

#: package → packages (or external modules) it must never import, directly or through others. The
#: procedure side (ground) never reaches ROS or habitat code; the habitat side never knows
#: procedures; the robot's planner and AT server run on a real robot too, so they never need the simulator.
FORBIDDEN = {
    # the executive runs onboard too: the ground's records (and their database libraries) are not its
    "pride": (
        "rclpy",
        "bridge",
        "at_ros",
        "sim",
        "starlette",
        "uvicorn",
        "records",
        "sqlalchemy",
        "alembic",
        "psycopg",
    ),
    # the files people write, read and checked: nothing that runs them, stores them or reaches a robot
    "procedure_language": ("pride", "records", "rclpy", "bridge", "at_ros", "sim", "starlette", "sqlalchemy"),
    # the ground's records are a store: no web server, no ROS, no console above them
    "records": ("rclpy", "bridge", "at_ros", "sim", "console", "onboard", "starlette", "uvicorn"),
    "console": ("rclpy", "bridge", "at_ros", "sim"),
    # what consoles, runners and agents agree on through the ground database: no web server, no ROS
    "ground": ("rclpy", "bridge", "at_ros", "sim", "console", "onboard", "starlette", "uvicorn"),
    # an agent reaches the ground only: never a robot, a bridge or the habitat's executive directly
    "agent": ("rclpy", "bridge", "at_ros", "sim", "onboard"),
    # the onboard executive runs PAX on the habitat: procedures, but no web or ROS stack of its own
    "onboard": ("rclpy", "bridge", "at_ros", "sim", "console", "starlette", "uvicorn"),
    "bridge": ("pride",),
    "at_ros": ("pride", "sim"),
    "sim": ("pride",),
    "perception": ("pride", "sim"),
    # the conformance suite judges servers: it shares no code with the one it judges, nor with its clients
    "interop": ("bridge", "rosbridge_wire", "pride", "rclpy"),
}


#: The allowed import order: each package and the Caretaker packages it may import. Two columns
#: on two leaves, ``datafile`` (the reader of every user file) and ``rosbridge_wire`` (the rosbridge
#: vocabulary and login of the bridge and its clients): the procedure side (``procedure_language``:
#: procedures, SysReps and bindings read and checked; ``pride``: the executive; ``records``: the
#: audit log, releases, robot control and the consoles' tables in the ground database, also the
#: onboard executive's SQLite log; the ground ``console`` on top of them) and the robot side
#: (``at_ros``, ``sim``, ``bridge``), joined only by the launcher ``caretaker``.
MAY_IMPORT = {
    "datafile": set(),
    "rosbridge_wire": set(),
    "procedure_language": {"datafile", "rosbridge_wire"},
    "pride": {"datafile", "procedure_language", "rosbridge_wire"},
    "records": {"procedure_language", "pride"},
    "ground": {"records"},
    # the console builds the onboard unit it hands to a supervisor
    "console": {"datafile", "procedure_language", "pride", "records", "rosbridge_wire", "ground", "onboard"},
    "onboard": {"datafile", "procedure_language", "pride", "records", "rosbridge_wire"},
    # assistant agents reach the ground as a console does, through its records and its forwarding
    "agent": {"datafile", "procedure_language", "pride", "records", "console", "ground"},
    "ros_process": set(),
    "bridge": {"datafile", "rosbridge_wire", "ros_process"},
    "at_ros": {"datafile", "ros_process"},
    "sim": {"datafile", "ros_process"},
    "perception": {"at_ros", "ros_process"},
    "interop": set(),
    "caretaker": {
        "interop",
        "datafile",
        "rosbridge_wire",
        "procedure_language",
        "pride",
        "records",
        "console",
        "ground",
        "agent",
        "onboard",
        "bridge",
        "at_ros",
        "sim",
        "perception",
        "ros_process",
    },
}


def declared_packages() -> dict[str, Path]:
    """Top-level package name → folder, as pyproject.toml declares them."""
    setup = tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]
    folders = setup.get("package-dir", {})
    return {name: REPO / folders.get(name, name) for name in setup["packages"] if "." not in name}


def modules(packages: dict[str, Path]) -> dict[str, Path]:
    """Every module of the packages: dotted name → file."""
    found: dict[str, Path] = {}
    for package, folder in packages.items():
        for path in sorted(folder.rglob("*.py")):
            parts = [package, *path.relative_to(folder).with_suffix("").parts]
            if parts[-1] == "__init__":
                parts.pop()
            found[".".join(parts)] = path
    return found


def imported(name: str, path: Path) -> Iterator[str]:
    """The dotted names a module imports (relative imports resolved)."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            yield from (alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - node.level + 1]
                base = ".".join([*anchor, base] if base else anchor)
            yield base
            yield from (f"{base}.{alias.name}" for alias in node.names)


@cache
def module_graph() -> dict[str, set[str]]:
    """Module → the project modules and external top-level modules it imports (read once: the
    tests only look at it)."""
    known = modules(declared_packages())
    graph: dict[str, set[str]] = {}
    for name, path in known.items():
        targets = set()
        for target in imported(name, path):
            if target in known:
                targets.add(target)
            elif target.rpartition(".")[0] not in known:  # "from pkg.mod import function" names pkg.mod
                targets.add(target.split(".")[0])
        targets.discard(name)
        graph[name] = targets
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """One cycle through each strongly connected component of more than one node (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    components: list[set[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(graph.get(node, ())):
            if target not in graph:
                continue
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = set()
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.add(member)
                if member == node:
                    break
            if len(component) > 1:
                components.append(component)

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return [_cycle_in(graph, component) for component in components]


def _cycle_in(graph: dict[str, set[str]], component: set[str]) -> list[str]:
    """A shortest cycle through the component's first member, as a path that ends where it starts."""
    start = min(component)
    paths = {start: [start]}
    frontier = [start]
    while frontier:
        following = []
        for node in frontier:
            for target in sorted(graph[node] & component):
                if target == start:
                    return [*paths[node], start]
                if target not in paths:
                    paths[target] = [*paths[node], target]
                    following.append(target)
        frontier = following
    raise AssertionError(f"no cycle in {component}")


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    packages = set(declared_packages())
    collapsed: dict[str, set[str]] = {package: set() for package in packages}
    for name, targets in graph.items():
        top = name.split(".")[0]
        collapsed[top] |= {t.split(".")[0] for t in targets if t.split(".")[0] in packages} - {top}
    return collapsed


def chain(graph: dict[str, set[str]], package: str, forbidden: str) -> list[str] | None:
    """A chain of imports from a module of ``package`` to ``forbidden`` (a package or external module)."""
    starts = sorted(m for m in graph if m.split(".")[0] == package)
    paths = {m: [m] for m in starts}
    frontier = list(starts)
    while frontier:
        following = []
        for node in frontier:
            for target in sorted(graph.get(node, ())):
                if target.split(".")[0] == forbidden:
                    return [*paths[node], target]
                if target in graph and target not in paths:
                    paths[target] = [*paths[node], target]
                    following.append(target)
        frontier = following
    return None


def test_packages_are_discovered_from_pyproject() -> None:
    packages = declared_packages()
    assert {"caretaker", "pride", "console", "bridge", "at_ros", "sim"} <= set(packages)
    assert all((folder / "__init__.py").is_file() for folder in packages.values())


def test_packages_import_only_what_the_order_allows() -> None:
    packages = package_graph(module_graph())
    assert set(packages) == set(MAY_IMPORT), "a package is missing from MAY_IMPORT (or gone)"
    wrong = {
        package: sorted(used - MAY_IMPORT[package]) for package, used in packages.items() if used - MAY_IMPORT[package]
    }
    assert not wrong, f"imports against the package order: {wrong}"


def test_no_import_cycle_between_packages() -> None:
    found = cycles(package_graph(module_graph()))
    assert not found, "package import cycles: " + "; ".join(" → ".join(c) for c in found)


def test_no_import_cycle_between_modules() -> None:
    found = cycles(module_graph())
    assert not found, "module import cycles: " + "; ".join(" → ".join(c) for c in found)


@pytest.mark.parametrize(("package", "forbidden"), [(p, f) for p, fs in FORBIDDEN.items() for f in fs])
def test_forbidden_imports(package: str, forbidden: str) -> None:
    found = chain(module_graph(), package, forbidden)
    assert found is None, f"{package} must not import {forbidden}: " + " → ".join(found or [])


def test_the_checker_finds_a_cycle_and_a_chain() -> None:
    graph = {"a.x": {"b.y"}, "b.y": {"a.z"}, "a.z": {"a.x", "rclpy"}}
    assert cycles(graph) == [["a.x", "b.y", "a.z", "a.x"]]
    assert chain(graph, "a", "rclpy") == ["a.z", "rclpy"]


def test_the_stack_does_not_import_the_demo() -> None:
    """``caretaker demo`` builds on ``caretaker.stack``, not the reverse."""
    assert "caretaker.demo" not in module_graph()["caretaker.stack"]
