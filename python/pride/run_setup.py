"""A run's set-up, done one way by every launcher: the console, ``caretaker run`` and the habitat.

Before a run reaches its robot, three decisions are made once and carried together: what runs
(the procedure checked against the SysReps, :class:`procedure_language.lint.CheckedProcedure`), where (the
robot side its binding reaches, :class:`pride.robot_sides.RobotSide`: the binding file, its
deployment and which commands need a second operator's approval there), and as what (the run id, made here, and the
version it runs, decided by the launcher's rule: the ground's release history, or the version a
habitat unit carries). :meth:`RunSetup.executive` and :meth:`RunSetup.resumed` then build the
:class:`pride.executive.Executive` from it, so each launcher has one place that builds one.

SysRep folders are read one way too (:func:`load_sysreps`): every ``*.yaml`` of each folder, and
an id declared twice, in one folder or across folders, is refused naming both files.
"""

from __future__ import annotations

import secrets
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from pride.events import Event, Journal
from pride.executive import Executive, Mode
from pride.robot_sides import RobotSide
from pride.run_control import ControlStore
from pride.run_version import RunVersion
from pride.systems import SystemGateway
from procedure_language.lint import CheckedProcedure, check_procedure
from procedure_language.sysrep import SysRep, SysRepError, load_sysrep_dir

__all__ = ["RunSetup", "VersionRule", "load_sysreps", "new_run_id"]

#: How a launcher decides the version a new run runs, once the procedure is checked and its robot
#: side known; it raises to refuse the run (e.g. :class:`records.releases.ReleaseRefused`).
VersionRule = Callable[[CheckedProcedure, RobotSide], RunVersion | None]


def load_sysreps(directories: Iterable[str | Path]) -> dict[str, SysRep]:
    """Every SysRep of ``directories``, by id.

    Raises:
        SysRepError: a file is invalid, or two files (in one folder or two) declare the same id;
            the message names both files.
    """
    sysreps: dict[str, SysRep] = {}
    for directory in directories:
        for sysrep_id, sysrep in load_sysrep_dir(directory).items():
            if sysrep_id in sysreps:
                raise SysRepError(
                    sysrep.path, 0, "id", f"duplicate SysRep id {sysrep_id!r} (also in {sysreps[sysrep_id].path})"
                )
            sysreps[sysrep_id] = sysrep
    return sysreps


def new_run_id(procedure_id: str) -> str:
    """A new run's id: the procedure, when it started (UTC), and 16 random bits against a clash
    of two starts in one second (the audit log refuses a second ``run_started`` of one id anyway)."""
    return f"{procedure_id}-{datetime.now(UTC):%Y%m%dT%H%M%SZ}-{secrets.token_hex(2)}"


@dataclass(frozen=True)
class RunSetup:
    """What one run is set up from, decided once before its robot is reached."""

    checked: CheckedProcedure
    side: RobotSide
    run_id: str
    version: RunVersion | None = None

    @classmethod
    def prepare(
        cls,
        procedure: str | Path,
        side: RobotSide,
        sysreps: Mapping[str, SysRep],
        *,
        version: VersionRule | None = None,
        run_id: str | None = None,
    ) -> RunSetup:
        """Check ``procedure``, decide the version by ``version`` and make the run id (or take
        ``run_id``, which a habitat unit carries).

        Raises:
            procedure_language.diagnostics.ProcedureError: the procedure has errors (all of them listed).
            Whatever ``version`` raises to refuse the run.
        """
        checked = check_procedure(procedure, sysreps)
        decided = version(checked, side) if version is not None else None
        return cls(checked, side, run_id or new_run_id(checked.procedure.id), decided)

    @classmethod
    def resuming(
        cls, procedure: str | Path, side: RobotSide, sysreps: Mapping[str, SysRep], events: Sequence[Event]
    ) -> RunSetup:
        """The set-up of a recorded run going on: its id and version are those of its log
        (whether it may go on is the launcher's rule, :func:`records.releases.resume_refusal`)."""
        return cls(check_procedure(procedure, sysreps), side, events[0].run_id if events else "")

    def unserved(self, gateway: SystemGateway) -> str | None:
        """Why ``gateway`` cannot serve this run (systems the procedure uses that it lacks), or None."""
        missing = {system for system, _ in self.checked.procedure.uses} - gateway.system_ids()
        if not missing:
            return None
        return (
            f"binding {self.side.binding.name} serves no {', '.join(sorted(missing))}, "
            f"which {Path(self.checked.procedure.path).name} uses"
        )

    def executive(
        self, gateway: SystemGateway, journal: Journal, *, mode: Mode = Mode.MANUAL, control: ControlStore | None
    ) -> Executive:
        """The new run's executive (nothing happens until its ``start``)."""
        return Executive(
            self.checked,
            gateway,
            journal,
            run_id=self.run_id,
            mode=mode,
            control=control,
            approvals=self.side.approvals,
            version=self.version,
        )

    def resumed(
        self,
        gateway: SystemGateway,
        journal: Journal,
        events: list[Event],
        user: str,
        *,
        mode: Mode | None = None,
        control: ControlStore | None,
        take_over: str | None = None,
        listeners: Sequence[Callable[[Event], None]] = (),
    ) -> Executive:
        """The recorded run's executive, going on from ``events`` (:meth:`Executive.resume`)."""
        return Executive.resume(
            self.checked,
            gateway,
            journal,
            events,
            user,
            mode=mode,
            control=control,
            take_over=take_over,
            approvals=self.side.approvals,
            listeners=listeners,
        )
