"""What the ground must know of the robot side a binding reaches: is it a simulator, and which
commands need a second operator's approval there.

Why on the ground: the rules are the ground's to enforce (a draft runs only as a rehearsal, and
only against a simulator; critical commanding, :mod:`pride.approvals`), but they are properties of
the robot side, so they live in its deployment file (``simulator: true``, ``critical_commanding:``)
next to everything else about it. The ground finds the deployment that serves a binding: one
named explicitly (``caretaker run --deployment``, ``caretaker serve --deployments DIR``), a shipped
one, or one beside the binding file (a robot folder ``caretaker new robot`` wrote), whose
``bindings:`` lists that very file. Only these two keys (and ``name``, ``bindings``) are read here;
``caretaker check`` checks the rest of the file.

A binding no deployment serves is a robot side nobody described: not a simulator, and hazardous
commands need approval (the safe default). Systems a test substitutes in the runner's own process
(``PRIDE_GATEWAY``, :mod:`pride.gateways`) are simulated by construction: there is no robot.
"""

from __future__ import annotations

import logging
import os
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from datafile import DataFileError, Field, load_file
from pride.approvals import ApprovalPolicy, policy_from
from pride.gateways import GATEWAY_ENV

__all__ = ["SHIPPED_DEPLOYMENTS", "RobotSide", "robot_side_for", "simulator_flag"]

log = logging.getLogger(__name__)

_REPO = Path(__file__).resolve().parents[2]
#: The shipped deployments, and the shipped bindings a bare name in them (``bindings: [iva]``) names.
SHIPPED_DEPLOYMENTS = _REPO / "deployments"
_SHIPPED_BINDINGS = _REPO / "sysrep" / "bindings"


@dataclass(frozen=True)
class RobotSide:
    """The robot side a binding reaches, as its deployment describes it."""

    binding: Path
    deployment: Path | None  # None: no deployment serves the binding
    simulator: bool
    approvals: ApprovalPolicy = field(default_factory=lambda: policy_from(None))

    def rehearsal_refusal(self) -> str | None:
        """Why a rehearsal may not run against this robot side (None: it may)."""
        if self.simulator:
            return None
        if self.deployment is None:
            return (
                f"a rehearsal runs only against a simulator, and no deployment serves {self.binding} "
                "(name the simulator's deployment, with simulator: true)"
            )
        return f"a rehearsal runs only against a simulator, and {self.deployment} is not one (no simulator: true)"


def simulator_flag(f: Field | None) -> bool:
    """A deployment's ``simulator:`` (absent: false, a real robot)."""
    return f.boolean() if f is not None else False


def robot_side_for(binding: Path, *, deployments: Sequence[Path] = ()) -> RobotSide:
    """The robot side ``binding`` reaches: the first deployment serving it among ``deployments``
    (files or folders of them), the shipped ones and those beside the binding.

    Raises:
        DataFileError: the deployment that serves it has a bad ``simulator`` or ``critical_commanding``.
    """
    binding = binding.resolve()
    in_process = bool(os.environ.get(GATEWAY_ENV))
    for path in _candidates([*deployments, SHIPPED_DEPLOYMENTS, binding.parent]):
        root = _serving(path, binding)
        if root is not None:
            return RobotSide(
                binding,
                path,
                simulator=in_process or simulator_flag(root.get("simulator")),
                approvals=policy_from(root.get("critical_commanding")),
            )
    return RobotSide(binding, None, simulator=in_process)


def _candidates(places: Iterable[Path]) -> Iterable[Path]:
    seen: set[Path] = set()
    for place in places:
        files = sorted(place.glob("*.yaml")) if place.is_dir() else [place]
        for path in files:
            if path.resolve() not in seen:
                seen.add(path.resolve())
                yield path


def _serving(path: Path, binding: Path) -> Field | None:
    """The deployment file's root if it is a deployment whose ``bindings:`` lists ``binding``."""
    try:
        root = load_file(path)
        if root.node.kind != "mapping" or not root.has("bindings") or not root.has("scene"):
            return None  # another kind of file beside the binding
        for each in root["bindings"].sequence():
            named = each.file_path(shipped=_SHIPPED_BINDINGS, what="binding", must_exist=False)
            if named.resolve() == binding:
                return root
    except DataFileError as exc:
        log.warning("not reading %s as a deployment: %s", path, exc)
    return None
