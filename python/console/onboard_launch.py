"""Starting an onboard run from the console ("run on the habitat"), and attaching a new supervisor to one.

The console does not supervise the habitat's run itself. With ``caretaker serve --via-supervisor``
it builds the unit here and hands it to the ``caretaker supervise`` that keeps the binding's
habitat session open (:func:`hand_onboard`); the supervisor uplinks it, keeps the ground's record
and hosts the run in the ground database, and this console waits only until the habitat took the
unit. A fleet's ground then starts no process per run. Otherwise it starts, on its own host, the
runner an operator would start at a terminal (``caretaker run PROC --onboard``, or ``caretaker run
--attach RUN`` for a run whose supervisor is gone), with ``--at-consoles`` so that a hold waits for
an operator at a console instead of stopping the run. The runner lints, uplinks, keeps the
ground's record and hosts the run in the ground database, so this console (and every other) shows
it as any hosted run, and operators' actions are forwarded to it. It outlives a console that
stops: the habitat's run must not lose its supervisor because a browser's server restarted.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from datafile import DataFileError
from ground.handed_run import HandedRun
from onboard.downlink import unit_for_run
from pride.approvals import APPROVER_PASSWORD_ENV
from pride.executive import Mode
from pride.run_section import SectionError
from pride.run_setup import RunSetup
from procedure_language.binding import read_binding
from records.audit_log import AuditLog
from records.onboard_handoffs import SUPERVISOR_WITHIN_S, TAKEN
from records.proposal_runs import ProposalNotRunnable, proposal_taken

__all__ = ["LaunchRefused", "SecondOperator", "attach_onboard", "hand_onboard", "launch_onboard"]

log = logging.getLogger(__name__)

#: How long the start waits for the habitat to accept the unit (the runner keeps trying after
#: that, until the unit's own lifetime runs out).
READY_WITHIN_S = 60.0


@dataclass(frozen=True)
class SecondOperator:
    """The second operator who approves an onboard unit's commands at this console, with the
    password they signed it with: the runner checks it again against the accounts before the unit
    goes up, as it does for ``caretaker run --approver`` at a terminal."""

    user: str
    password: str = field(repr=False)


class LaunchRefused(RuntimeError):
    """The runner ended before the habitat accepted the unit (``ended``: nothing will run), or has
    not heard yet: the text is what it said (lint errors, the habitat's refusal, an unreachable
    habitat) and where its log is."""

    def __init__(self, message: str, *, ended: bool = True) -> None:
        super().__init__(message)
        self.ended = ended


def launch_onboard(
    procedure: Path,
    binding: Path,
    *,
    user: str,
    autonomous: bool,
    approver: SecondOperator | None = None,
    rehearsal: bool = False,
    deployments: Sequence[Path] = (),
    db_url: str,
    sysreps: Sequence[Path],
    rosbridge: str | None,
    ready_within: float = READY_WITHIN_S,
    proposal: int | None = None,
    confirm_manual: bool = False,
) -> str:
    """Start the supervising runner and wait until the habitat accepted the unit; the run's id.
    ``proposal``: the accepted proposal the run answers, its values going up with it;
    ``confirm_manual``: the habitat marks manual instructions done by itself.

    Raises:
        LaunchRefused: as :func:`_launch` says.
    """
    arguments = [
        str(procedure),
        "--binding",
        str(binding),
        "--onboard",
        "--auto" if autonomous else "--manual",
        *(["--rehearsal"] if rehearsal else []),
        *(option for path in deployments for option in ("--deployment", str(path))),
        *(["--approver", approver.user] if approver else []),
        *(["--proposal", str(proposal)] if proposal is not None else []),
        *(["--confirm-manual"] if confirm_manual else []),
    ]
    secrets = {APPROVER_PASSWORD_ENV: approver.password} if approver else {}
    still = "keeps sending the unit until it expires, and the run appears in the list if the habitat accepts it"
    return _launch(
        arguments, secrets, still, user=user, db_url=db_url, sysreps=sysreps, rosbridge=rosbridge, within=ready_within
    )


def hand_onboard(
    setup: RunSetup,
    binding: Path,
    audit: AuditLog,
    *,
    user: str,
    mode: Mode,
    approver: SecondOperator | None,
    rosbridge: str | None,
    proposal: int | None = None,
    confirm_manual: bool = False,
    values: Mapping[str, str] | None = None,
    supervisor_within: float = SUPERVISOR_WITHIN_S,
    ready_within: float = READY_WITHIN_S,
) -> str:
    """Build the unit of the run ``setup`` prepares and hand it to the supervisors of ``binding``
    (their holds waiting for an operator at a console); the run's id once the habitat took it.
    ``approver`` was checked at this console (:func:`console.request_bodies.second_operator`);
    ``proposal``: the accepted proposal the run answers, taken here as the runner takes it;
    ``values``: the procedure's inputs going up with it (``--set``; a console's start gives none,
    and the habitat asks an operator at a console).

    Raises:
        LaunchRefused: the binding cannot reach the habitat, the proposal or the unit is refused
            (nothing went up), no supervisor took it within ``supervisor_within`` (withdrawn), or
            the habitat refused it; ``ended=False`` if the habitat has not answered within
            ``ready_within`` (its supervisor keeps trying, and the run appears once it is taken).
    """
    try:
        endpoint = read_binding(binding).endpoint(rosbridge)
    except (DataFileError, OSError) as exc:
        raise LaunchRefused(f"cannot open binding {binding.name}: {exc}") from None
    if endpoint.secret is None:
        raise LaunchRefused(
            f"{binding.name} has no security.secret_file: an onboard unit is signed with the link's secret"
        )
    given = dict(values or {})
    try:
        taken = proposal_taken(proposal, audit, user, setup, given)
        unit = unit_for_run(
            setup,
            endpoint,
            binding=binding.name,
            user=user,
            mode=mode,
            values=given,
            approver=approver.user if approver else None,
            proposal=taken,
            confirm_manual=confirm_manual,
        )
    except (ProposalNotRunnable, SectionError, ValueError) as exc:
        raise LaunchRefused(f"{setup.checked.procedure.path} cannot go up to the habitat: {exc}") from None
    handed = HandedRun(audit, unit.run_id)
    try:
        handed.hand(binding=unit.binding, unit_json=unit.to_json(), user=user, at_consoles=True)
        if handed.taken(supervisor_within) is None:
            raise LaunchRefused(
                f"no supervisor of {binding.name} took run {unit.run_id} within {supervisor_within:g} s: withdrawn, "
                f"nothing went up (is `caretaker supervise --binding {binding}` running on this database?)"
            )
        handoff, ready = handed.ready(ready_within)
    finally:
        handed.close()
    if not ready and handoff.state != TAKEN:  # ended, or left, without the habitat taking it
        raise LaunchRefused(f"run {unit.run_id} did not start on the habitat: {handoff.message or handoff.state}")
    if not ready:
        raise LaunchRefused(
            f"no answer from the habitat within {ready_within:.0f} s; {handoff.supervisor} keeps sending the unit "
            "until it expires, and the run appears in the list if the habitat accepts it",
            ended=False,
        )
    log.info("onboard run %s handed by %s to %s", unit.run_id, user, handoff.supervisor)
    return unit.run_id


def attach_onboard(
    run_id: str,
    binding: Path,
    *,
    user: str,
    db_url: str,
    sysreps: Sequence[Path],
    rosbridge: str | None,
    ready_within: float = READY_WITHIN_S,
) -> str:
    """Start a supervising runner for onboard run ``run_id``, whose supervisor is gone
    (``caretaker run --attach``), and wait until it follows the run again; the run's id.

    Raises:
        LaunchRefused: as :func:`_launch` says (another supervisor holds the run, the habitat
            does not know it or cannot be reached).
    """
    arguments = ["--attach", run_id, "--binding", str(binding)]
    still = "keeps trying to reach the habitat, and the run shows as live again once it follows it"
    return _launch(
        arguments, {}, still, user=user, db_url=db_url, sysreps=sysreps, rosbridge=rosbridge, within=ready_within
    )


def _launch(
    arguments: Sequence[str],
    secrets: Mapping[str, str],
    still_trying: str,
    *,
    user: str,
    db_url: str,
    sysreps: Sequence[Path],
    rosbridge: str | None,
    within: float,
) -> str:
    """Run ``caretaker run ARGUMENTS`` as ``user``, answering at the consoles, on the ground
    database ``db_url``; the run's id from its ``READY run`` line. ``secrets`` go in its environment;
    ``still_trying``: what a runner that has no answer yet goes on doing.

    The runner writes to a log file of its own (named in the console's log), not to a pipe: it
    must go on printing after this console is gone.

    Raises:
        LaunchRefused: the runner could not start, ended before ``READY run``, or is still waiting
            for the habitat's answer after ``within`` (it is left running: the habitat may yet
            answer, and then the run appears in the list).
    """
    command = [
        str(Path(sys.executable).with_name("caretaker")),
        "run",
        *arguments,
        "--at-consoles",
        "--user",
        user,
        *(option for path in sysreps for option in ("--sysrep-dir", str(path))),
        *(["--rosbridge", rosbridge] if rosbridge else []),
    ]
    with tempfile.NamedTemporaryFile("w", prefix="caretaker-onboard-runner-", suffix=".log", delete=False) as out:
        logfile = Path(out.name)
        try:
            runner = subprocess.Popen(
                command,
                stdin=subprocess.DEVNULL,
                stdout=out,
                stderr=subprocess.STDOUT,
                # not on the command line, where any user of the host sees them: passwords
                env={**os.environ, "CARETAKER_DB": db_url, **secrets},
                start_new_session=True,  # not stopped with the console (a Ctrl-C at its terminal)
            )
        except OSError as exc:
            raise LaunchRefused(f"cannot start the runner ({command[0]}): {exc}") from None
    log.info("onboard runner %d for %s (caretaker run %s); its log: %s", runner.pid, user, " ".join(arguments), logfile)
    ended = threading.Event()

    def reap() -> None:  # a runner that ends is waited for, whether or not the start still waits on it
        runner.wait()
        ended.set()

    threading.Thread(target=reap, name=f"runner-{runner.pid}", daemon=True).start()
    run_id = _await_ready(logfile, ended, within)
    said = logfile.read_text(errors="replace").strip()
    if run_id is None and ended.is_set():
        raise LaunchRefused(f"{said or 'the runner ended without a word'}\n(runner log: {logfile})")
    if run_id is None:
        raise LaunchRefused(
            f"no answer from the habitat within {within:.0f} s; the runner (pid {runner.pid}) {still_trying} "
            f"(runner log: {logfile}):\n{said}",
            ended=False,
        )
    log.info("onboard run %s supervised for %s (runner pid %d)", run_id, user, runner.pid)
    return run_id


def _await_ready(logfile: Path, ended: threading.Event, within: float) -> str | None:
    """The run id from the runner's ``READY run <id>`` line, read as the runner writes it; None if
    it ended first or ``within`` ran out. The file is read again each time the runner may have
    written (a tenth of a second apart: a file gives no event to wait on)."""
    deadline = time.monotonic() + within
    while True:
        for line in logfile.read_text(errors="replace").splitlines():
            if line.startswith("READY run "):
                return line.split()[-1]
        if ended.is_set() or time.monotonic() >= deadline:
            return None
        ended.wait(0.1)
