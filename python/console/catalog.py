"""What a console offers to run: procedures, bindings and SysReps by file name, and each binding's camera.

Procedures and bindings are chosen by file name from the configured folders, so a request can
never name an arbitrary path on the server (an unknown name is refused, 400, listing the known
ones).
"""

from __future__ import annotations

import argparse
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path

from console.actions import ActionRefused
from datafile import DataFileError
from pride.robot_sides import RobotSide, robot_side_for

__all__ = [
    "CameraSettings",
    "Catalog",
    "catalog_options",
    "per_binding",
    "rosbridge_for",
    "rosbridge_overrides",
]

REPO = Path(__file__).resolve().parents[2]


@dataclass(frozen=True)
class CameraSettings:
    """Which camera the live feed captures while each binding's robot moves, and how often.

    ``cameras`` maps a binding file name to a camera of its robot's scene ("" to every binding not
    named): robots name their cameras differently (IVA's rack camera ``scene``, EVA's ``ee_camera``).
    A binding without one has no live feed.
    """

    cameras: Mapping[str, str] = field(default_factory=dict)
    period: float = 0.5

    def camera_for(self, binding: str) -> str | None:
        return self.cameras.get(binding, self.cameras.get(""))


@dataclass(frozen=True)
class Catalog:
    """Where procedures, bindings and SysReps are read from, and the deployments that say what
    the robot side of each binding is (a simulator? which commands need approval?) besides the
    shipped ones and those beside a binding (:mod:`pride.robot_sides`)."""

    procedures: Path
    bindings: Path
    sysreps: tuple[Path, ...]  # SysRep folders, read as one (a duplicate id refused)
    deployments: tuple[Path, ...] = ()

    def procedure_files(self) -> list[str]:
        return sorted(p.name for p in self.procedures.glob("*.xml"))

    def binding_files(self) -> list[str]:
        return sorted(p.name for p in self.bindings.glob("*.yaml")) if self.bindings.is_dir() else []

    def procedure_path(self, name: str) -> Path:
        return _choose(self.procedures, name, self.procedure_files(), "procedure")

    def binding_path(self, name: str) -> Path:
        return _choose(self.bindings, name, self.binding_files(), "binding")

    def shown(self, procedure_name: str) -> str:
        """A procedure as messages name it: ``procedures/x.xml``."""
        return f"{self.procedures.name}/{procedure_name}"

    def robot_side(self, binding_name: str) -> RobotSide:
        """The robot side a binding reaches, as its deployment describes it; ActionRefused when
        that deployment's simulator or critical_commanding is wrong."""
        try:
            return robot_side_for(self.binding_path(binding_name), deployments=self.deployments)
        except DataFileError as exc:
            raise ActionRefused(422, f"the deployment serving {binding_name} cannot be used: {exc}") from None


def _choose(directory: Path, name: str, known: list[str], what: str) -> Path:
    if name not in known:
        raise ActionRefused(400, f"unknown {what} {name!r}; known: {', '.join(known) or 'none'} (in {directory})")
    return directory / name


def catalog_options(parser: argparse.ArgumentParser) -> None:
    """``--procedures``, ``--bindings``, ``--sysreps`` and ``--rosbridge``: what a console (and an
    agent, which must see what the consoles see) offers, and where its robots are, with the same
    defaults everywhere."""
    parser.add_argument("--procedures", type=Path, default=REPO / "procedures", help="directory of procedure XML files")
    parser.add_argument(
        "--bindings", type=Path, default=REPO / "sysrep" / "bindings", help="directory of binding files"
    )
    parser.add_argument(
        "--sysreps",
        type=Path,
        action="append",
        metavar="DIR",
        help=f"directory of SysRep YAML files (repeatable; default {REPO / 'sysrep'}); an id twice is refused",
    )
    parser.add_argument(
        "--rosbridge",
        metavar="[BINDING=]URL",
        action="append",
        default=[],
        help="replace the rosbridge URL of the binding file BINDING (e.g. eva.yaml=ws://127.0.0.1:9091), "
        "or of every binding without BINDING=; repeat for several robots",
    )


def per_binding(flag: str, options: list[str], expected: str, valid: Callable[[str], object]) -> dict[str, str]:
    """``[BINDING=]VALUE`` options as binding file name -> value ("" for every binding); ValueError
    says what is wrong."""
    values: dict[str, str] = {}
    for option in options:
        binding, _, value = option.partition("=") if "=" in option.split("://", 1)[0] else ("", "", option)
        if not valid(value):
            raise ValueError(f"{flag} {option}: expected [BINDING=]{expected}")
        if binding in values:
            raise ValueError(
                f"{flag} {option}: {'binding ' + binding if binding else 'every binding'} was given one already"
            )
        values[binding] = value
    return values


def rosbridge_overrides(options: list[str]) -> dict[str, str]:
    """``--rosbridge`` options: binding file name (or "" for every binding) -> URL; ValueError says what is wrong."""
    return per_binding(
        "--rosbridge", options, "ws://HOST:PORT or wss://HOST:PORT", lambda url: url.startswith(("ws://", "wss://"))
    )


def rosbridge_for(overrides: Mapping[str, str], binding: str) -> str | None:
    """The rosbridge URL given for a binding file (or for every binding); None: the binding's own."""
    return overrides.get(binding, overrides.get(""))
