"""``caretaker check FILE...``: check any data file Caretaker reads, without starting anything.

Scenes, robot configs, AT templates, deployments, SysReps and bindings are each checked by the
loader that reads them for real (one mechanism, :mod:`datafile`), so what passes here loads
there; a procedure (``.xml``) is checked as ``caretaker lint`` checks it, against the shipped
SysReps, one line per problem. The kind of a file comes from its name and content (``--kind`` to say it); each file
gets one line, ``FILE: ok (kind)`` or the error ``file:line: key: problem``, and the exit code
is 1 if any file has an error. No input ends in a traceback.
"""

from __future__ import annotations

import argparse
import functools
import sys
from collections.abc import Callable
from pathlib import Path
from typing import Any

from datafile import DataFileError, load_file
from procedure_language.diagnostics import ProcedureError

__all__ = ["KINDS", "check_file", "detect_kind", "main"]


def _scene(path: Path) -> Any:
    from sim.scene import load_scene

    return load_scene(path)


def _robot(path: Path) -> Any:
    from at_ros.robot_config import load_robot_config

    return load_robot_config(path)


def _template(path: Path) -> Any:
    from at_ros.library import load_template

    return load_template(path)


def _deployment(path: Path) -> Any:
    from caretaker.deployment import load_deployment

    return load_deployment(path)


def _sysrep(path: Path) -> Any:
    from procedure_language.sysrep import load_sysrep

    return load_sysrep(path)


def _binding(path: Path) -> Any:
    from procedure_language.binding import read_binding

    return read_binding(path)


def _urdf(path: Path) -> Any:
    from datafile.urdf import read_urdf

    return read_urdf(path)


@functools.cache
def _shipped_sysreps() -> Any:
    """The shipped SysReps, read once however many procedures one ``check`` is given."""
    from caretaker.command_options import load_sysreps

    return load_sysreps(None)


def _procedure(path: Path) -> Any:
    from procedure_language.lint import lint_file

    problems = lint_file(path, _shipped_sysreps())
    if problems:
        raise ProcedureError(problems)
    return None


#: kind -> (loader, what it is called in messages)
KINDS: dict[str, tuple[Callable[[Path], Any], str]] = {
    "scene": (_scene, "a scene"),
    "robot": (_robot, "a robot config"),
    "template": (_template, "an AT template"),
    "deployment": (_deployment, "a deployment"),
    "sysrep": (_sysrep, "a SysRep"),
    "binding": (_binding, "a binding"),
    "procedure": (_procedure, "a procedure, linted against the shipped SysReps"),
    "urdf": (_urdf, "a URDF: it parses and every mesh it names on this host is there"),
}
#: A top-level key that only one kind of YAML file has, in the order they are tried.
_SIGNATURE_KEYS = (
    ("robot_name", "robot"),
    ("systems", "binding"),
    ("commands", "sysrep"),
    ("telemetry", "sysrep"),
    ("templates", "deployment"),
    ("bodies", "scene"),
    ("physics_rate_hz", "scene"),
    ("slots", "scene"),
)


def detect_kind(path: Path) -> str:
    """The kind of ``path`` from its name (``.json`` is a template) or its top-level keys.

    Raises:
        DataFileError: the file does not parse, or it looks like none of the kinds.
    """
    if path.suffix.lower() == ".json":
        return "template"
    if path.suffix.lower() == ".xml":
        return "procedure"
    if path.suffix.lower() == ".urdf":
        return "urdf"
    root = load_file(path)
    keys = {key for key, _, _ in root.node.entries}
    for key, kind in _SIGNATURE_KEYS:
        if key in keys:
            return kind
    if "scene" in keys:
        return "deployment"
    if "robot" in keys:
        return "scene"
    if "id" in keys:
        return "sysrep"
    raise root.fail(
        "cannot tell what kind of file this is (a scene, robot config, deployment, SysRep or binding); use --kind"
    )


def check_file(path: Path, kind: str | None = None) -> str:
    """One line: ``FILE: ok (a scene)``, or the first error in the file.

    Raises:
        DataFileError: the error (its text is the line to print).
    """
    kind = kind or detect_kind(path)
    load, called = KINDS[kind]
    load(path)
    return f"{path}: ok ({called})"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="caretaker check", description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="+", metavar="FILE", type=Path)
    parser.add_argument(
        "--kind", choices=sorted(KINDS), help="what the files are (default: from each file's name and content)"
    )
    args = parser.parse_args(argv)
    # A message may quote the file's own bytes: never let printing it fail.
    out = open(sys.stdout.fileno(), "w", encoding="utf-8", errors="backslashreplace", closefd=False, buffering=1)  # noqa: SIM115
    failed = False
    for path in args.files:
        try:
            line = check_file(path, args.kind)
        except DataFileError as exc:
            line, failed = str(exc), True
        except ProcedureError as exc:  # one line per problem, as `caretaker lint` prints them
            line, failed = str(exc), True
        except Exception as exc:  # a loader bug: still one line, and it counts as an error
            line, failed = (
                f"{path}: internal error while checking ({type(exc).__name__}: {exc}); please report it",
                True,
            )
        print(line, file=out)
    out.flush()
    return 1 if failed else 0
