"""The options the procedure commands share (``caretaker lint``, ``run``, ``report``, ``release``, ``check``).

One reading of ``--sysrep-dir`` for every command: the shipped SysReps by default, each folder read
as every launcher reads them (:func:`pride.run_setup.load_sysreps`: a duplicate id is refused with
both files named).
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

from pride import run_setup
from pride.run_section import RunSection
from procedure_language.lint import CheckedProcedure
from procedure_language.sysrep import SysRep

__all__ = ["DEFAULT_SYSREP_DIR", "load_sysreps", "raw_option", "section_of", "sysrep_option"]

REPO = Path(__file__).resolve().parents[2]
DEFAULT_SYSREP_DIR = REPO / "sysrep"


def load_sysreps(directories: Sequence[str] | None) -> dict[str, SysRep]:
    """The SysReps of ``--sysrep-dir`` folders (default: the shipped ones)."""
    return run_setup.load_sysreps(directories or [DEFAULT_SYSREP_DIR])


def section_of(args: argparse.Namespace, checked: CheckedProcedure, values: dict[str, str]) -> RunSection | None:
    """``caretaker run --from/--to``: the part of the procedure to run, with ``--set``'s values for
    what it skips (None: the whole procedure)."""
    if args.from_step is None and args.to_step is None:
        return None
    return RunSection(args.from_step or checked.procedure.steps[0].id, args.to_step, values)


def sysrep_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--sysrep-dir",
        action="append",
        metavar="DIR",
        help=f"directory of SysRep *.yaml files (repeatable; default {DEFAULT_SYSREP_DIR})",
    )


def raw_option(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--raw",
        action="store_true",
        help="also show each command sent as the call (system.command(arg=value, ...), values in full), "
        "as the web view's raw-commands switch does",
    )
