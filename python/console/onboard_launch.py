"""Starting an onboard run from the console ("run on the habitat"), and attaching a new supervisor to one.

The console does not supervise the habitat's run itself. It starts, on its own host, the runner
an operator would start at a terminal (``caretaker run PROC --onboard``, or ``caretaker run
--attach RUN`` for a run whose supervisor is gone), with ``--at-consoles``
so that a hold waits for an operator at a console instead of stopping the run. The runner lints,
uplinks, keeps the ground's record and hosts the run in the ground database, so this console (and
every other) shows it as any hosted run, and operators' actions are forwarded to it. It outlives
a console that stops: the habitat's run must not lose its supervisor because a browser's server
restarted.
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

from pride.approvals import APPROVER_PASSWORD_ENV

__all__ = ["LaunchRefused", "SecondOperator", "attach_onboard", "launch_onboard"]

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
    via_supervisor: bool = False,
) -> str:
    """Start the supervising runner and wait until the habitat accepted the unit; the run's id.
    ``proposal``: the accepted proposal the run answers, its values going up with it;
    ``confirm_manual``: the habitat marks manual instructions done by itself; ``via_supervisor``: the
    runner hands the unit to a ``caretaker supervise`` of the binding and ends once the habitat took it.

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
        *(["--via-supervisor", "--no-follow"] if via_supervisor else []),
    ]
    secrets = {APPROVER_PASSWORD_ENV: approver.password} if approver else {}
    still = "keeps sending the unit until it expires, and the run appears in the list if the habitat accepts it"
    return _launch(
        arguments, secrets, still, user=user, db_url=db_url, sysreps=sysreps, rosbridge=rosbridge, within=ready_within
    )


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
