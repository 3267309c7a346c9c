"""The IVA procedure flown across the emulated link: a habitat host, a ground host, and what each saw.

Habitat namespace: ``caretaker up`` of the IVA habitat deployment (wss:// with a secret, the
command ledger's memory in a folder the test reads) and :mod:`habitat_probe` (what the arm really
did). Link namespace: ``caretaker link``. Ground namespace: ``caretaker run`` of the IVA
procedure, autonomous, with a ground binding that states the link (so every command goes
through the ledger), and its audit log in a SQLite file the test reads.

What the arm did is counted on the habitat (trajectory goals the simulation's controller carried
out, and the ledger's own records), never from the ground's log; the ground's audit log must
match it, command for command, with no false success (:func:`assert_flown_exactly_once`).
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import sqlite3
import subprocess
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any

import yaml

from caretaker.certs import make_link_credentials
from caretaker.processes import REPO, ManagedProcess
from console.accounts import AccountStore
from pride.events import Event, EventKind
from procedure_language.model import CallInstruction, CommandInstruction
from procedure_language.parser import load_procedure
from records.audit_chain import StoredEvent
from records.audit_log import AuditLog
from support.second_operator import APPROVED_BY_BOB, approver_env
from support.stack import write_deployment
from support.two_hosts import LinkProcess, TwoHosts

if TYPE_CHECKING:  # playwright is loaded by the browser flights only
    from playwright.sync_api import Page

PROCEDURE = REPO / "procedures" / "iva_cdra_filter_replacement.xml"
GROUND_BINDING = REPO / "sysrep" / "bindings" / "iva-ground.yaml"
PROBE = Path(__file__).with_name("habitat_probe.py")
BRIDGE_PORT = 9090
CLEAN_FILTER = "CDRA-F-0012"
#: The pull-out of the dirty filter: the execute the outages aim at.
PULL_OUT = "grasp_and_pull"
RUN_TIMEOUT_S = 900.0
#: What a console page shows waits on round trips over the 1.3 s link.
LINK_MS = 60_000


@dataclass
class Habitat:
    """``caretaker up`` in the habitat namespace, and the folder its ledger keeps its memory in."""

    up: ManagedProcess
    state_dir: Path

    def onboard_chain(self, run_id: str) -> list[StoredEvent]:
        """The onboard run's events as the habitat's own store holds them."""
        return onboard_chain(self.state_dir / "onboard", run_id)

    def onboard_actions(self) -> list[dict[str, Any]]:
        """Every operator action the onboard executive took, as it recorded them."""
        path = self.state_dir / "onboard" / "actions.jsonl"
        return [json.loads(line) for line in path.read_text().splitlines()]

    def ledger_records(self) -> list[dict[str, Any]]:
        """Every command the ledger executed (or refused), in the order it got them."""
        path = self.state_dir / "ledger" / "command_ledger.sqlite"
        with contextlib.closing(sqlite3.connect(f"file:{path}?mode=ro", uri=True)) as db:
            db.row_factory = sqlite3.Row
            return [dict(row) for row in db.execute("SELECT * FROM commands ORDER BY started")]


@dataclass
class Flight:
    hosts: TwoHosts
    habitat: Habitat
    probe: ManagedProcess
    link: LinkProcess
    binding: Path
    db_url: str
    credentials: dict[str, Path]
    time_scale: str

    @property
    def url(self) -> str:
        """The habitat's bridge as the ground reaches it: wss:// through the link."""
        return f"wss://{self.link.address[0]}:{self.link.address[1]}"

    def run(self, *extra: str, record: bool = True) -> ManagedProcess:
        """``caretaker run`` of the IVA procedure in the ground namespace, autonomous and unattended
        (``record``: with the clean filter's id, which 4.1 records, given on the command line); bob
        approves the hazardous unlock, at once (onboard: carried up in the unit)."""
        return self.hosts.caretaker(
            self.hosts.ground,
            "run",
            str(PROCEDURE),
            "--binding",
            str(self.binding),
            "--auto",
            "--user",
            "flight",
            "--db",
            self.db_url,
            "--confirm-manual",
            *APPROVED_BY_BOB,
            "--rehearsal",
            *([f"--set=clean_filter_id={CLEAN_FILTER}"] if record else []),
            *extra,
            ready=r"^READY run ",
            timeout=180,
        )

    def events(self, run_id: str) -> list[Event]:
        audit = AuditLog(self.db_url)
        try:
            return audit.events(run_id)
        finally:
            audit.close()

    def ground_chain(self, run_id: str) -> list[StoredEvent]:
        """The run's events as the ground's audit log stores them, with their hashes."""
        audit = AuditLog(self.db_url)
        try:
            return audit.stored_events(run_id)
        finally:
            audit.close()

    def goals(self) -> list[tuple[str, int]]:
        """Every arm trajectory goal that ended on the habitat: (id, status)."""
        return [
            (words[1], int(words[2])) for words in (line.split() for line in self.probe.output) if words[:1] == ["GOAL"]
        ]

    def await_execution(self, trajectory: str, timeout: float = RUN_TIMEOUT_S) -> str:
        """Block until the habitat's AT server executes ``trajectory``; return the probe's line."""
        return self.probe.wait_for_line(rf"^EXECUTING \S+ {trajectory}$", timeout)

    def await_motion(self, trajectory: str, timeout: float = RUN_TIMEOUT_S) -> None:
        """Block until the arm moves (anew) while the habitat's AT server executes ``trajectory``."""
        self.await_execution(trajectory, timeout)
        self.probe.wait_for_line(r"^MOVING ", 60, after=self.probe.printed)

    def kill_part(self, part: str) -> int:
        """SIGKILL one habitat part (``caretaker <part>``: a crash); ``caretaker up`` restarts it. Returns its pid."""
        for pid in self._habitat_pids():
            argv = Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")
            if len(argv) > 2 and argv[1].endswith(b"caretaker") and argv[2] == part.encode():
                os.kill(pid, signal.SIGKILL)
                return pid
        raise AssertionError(f"no caretaker {part} runs in {self.hosts.habitat.namespace}")

    def serve_console(
        self, operator: str, password: str, *, others: Mapping[str, str] | None = None
    ) -> tuple[ManagedProcess, str]:
        """``caretaker serve`` in the ground namespace on the ground's audit log, offering the ground
        binding, with ``operator`` (and ``others``: user → password) operators' accounts; (process, URL)."""
        bindings = self.hosts.folder / "bindings"
        bindings.mkdir(exist_ok=True)
        with contextlib.suppress(FileExistsError):
            (bindings / self.binding.name).symlink_to(self.binding)
        accounts = AccountStore(self.db_url)
        try:
            for user, secret in {operator: password, **(others or {})}.items():
                accounts.add(user, "operator", secret, name="Flight operator")
        finally:
            accounts.close()
        serve = self.hosts.caretaker(
            self.hosts.ground,
            "serve",
            "--port",
            "0",
            "--db",
            self.db_url,
            "--procedures",
            str(REPO / "procedures"),
            "--bindings",
            str(bindings),
            "--rosbridge",
            self.url,
            "--reports",
            str(self.hosts.folder / "reports"),
            timeout=120,
        )
        return serve, serve.wait_ready().split()[-1]

    @contextlib.contextmanager
    def console_page(self, url: str, operator: str, password: str, *, webgl: bool = False) -> Iterator[Page]:
        """Chromium in the ground namespace (as an operator's browser on the ground network; pipes
        pass through ``ip netns exec``), signed in to the console at ``url``; with ``webgl`` it
        draws the 3D view (WebGL on SwiftShader), which costs CPU while the arm moves."""
        from playwright.sync_api import sync_playwright

        from support.browser import WEBGL_ARGS

        wrapper = self.hosts.folder / "chromium-on-the-ground"
        wrapper.write_text(f'#!/bin/sh\nexec ip netns exec {self.hosts.ground.namespace} /usr/bin/chromium "$@"\n')
        wrapper.chmod(0o755)
        with sync_playwright() as driver:
            browser = driver.chromium.launch(
                executable_path=str(wrapper),
                headless=True,
                args=WEBGL_ARGS if webgl else ["--no-sandbox", "--disable-gpu", "--no-first-run"],
            )
            try:
                page = browser.new_page(viewport={"width": 1500, "height": 1000})
                page.set_default_timeout(LINK_MS)
                page.goto(url)
                page.fill("#user-id", operator)
                page.fill("#password", password)
                page.click("#sign-in-form button[type=submit]")
                yield page
            finally:
                browser.close()

    def restart_habitat_without_memory(self) -> Habitat:
        """A new habitat side after the old one died, its memory lost: a new state folder (a new
        ledger epoch, no AT instances), the simulation's world from the start."""
        state = self.hosts.folder / f"habitat-state-{len(self.hosts.processes)}"
        self.habitat = start_habitat(
            self.hosts, self.credentials, self.binding, state, time_scale=self.time_scale, onboard=False
        )
        return self.habitat

    def _habitat_pids(self) -> list[int]:
        listed = subprocess.run(
            ["ip", "netns", "pids", self.hosts.habitat.namespace],
            capture_output=True,
            text=True,
            check=True,
            timeout=30,
        ).stdout.split()
        return [int(pid) for pid in listed]


def onboard_chain(state_dir: Path, run_id: str) -> list[StoredEvent]:
    """The onboard run's events as the store of the onboard executive (``--state-dir``) holds them."""
    store = AuditLog(f"sqlite:///{state_dir / 'onboard.sqlite'}")
    try:
        return store.stored_events(run_id)
    finally:
        store.close()


def write_ground_binding(
    folder: Path,
    url: str,
    credentials: dict[str, Path],
    *,
    one_way_delay: float,
    outage_budget: float,
    robot: str = "iva",
) -> Path:
    """The shipped ground binding with this flight's URL, link and credentials (paths made absolute),
    naming ``robot``: ``iva-ground.yaml`` for the shipped ``iva``, else ``<robot>.yaml``, so that
    several habitats' bindings have names of their own (a handoff names its binding by file name)."""
    data = yaml.safe_load(GROUND_BINDING.read_text())
    data["robot"] = robot
    data["rosbridge"] = url
    data["link"] = {"one_way_delay": one_way_delay, "outage_budget": outage_budget}
    data["security"] = {"ca_file": str(credentials["ca.pem"]), "secret_file": str(credentials["rosbridge.secret"])}
    for system in data["systems"]:
        system["sysrep"] = str((GROUND_BINDING.parent / system["sysrep"]).resolve())
    path = folder / ("iva-ground.yaml" if robot == "iva" else f"{robot}.yaml")
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def start_habitat(
    hosts: TwoHosts,
    credentials: dict[str, Path],
    binding: Path,
    state_dir: Path,
    *,
    time_scale: str,
    onboard: bool,
    critical_commanding: dict[str, Any] | None = None,
    verbose: bool = False,
) -> Habitat:
    """``caretaker up`` of the IVA habitat deployment on the habitat's address, wss:// and a secret
    (``onboard``: with the onboard executive, serving units that name ``binding``;
    ``critical_commanding``: the deployment's, which the ground and the habitat both apply;
    ``verbose``: echoing its parts' output)."""
    deployment = write_deployment(
        hosts.folder,
        "iva-habitat",
        bridge={
            "address": "0.0.0.0",
            "port": BRIDGE_PORT,
            "certfile": str(credentials["bridge.pem"]),
            "keyfile": str(credentials["bridge.key"]),
            "auth_secret_file": str(credentials["rosbridge.secret"]),
        },
        state_dir=str(state_dir),
        bindings=[str(binding)],
        onboard=onboard,
        **({"critical_commanding": critical_commanding} if critical_commanding else {}),
    )
    up = hosts.caretaker(
        hosts.habitat,
        "up",
        str(deployment),
        "--bridge-address",
        hosts.habitat.address,
        "--time-scale",
        time_scale,
        *(["--verbose"] if verbose else []),
        ready=r"^READY stack ",
        timeout=240,
    )
    return Habitat(up, state_dir)


@contextlib.contextmanager
def flight(
    ros_env: dict[str, str],
    *,
    delay: float,
    link_options: Sequence[str] = (),
    time_scale: str = "1",
    paced: Mapping[str, float] | None = None,
    outage_budget: float = 120.0,
    onboard: bool = False,
    critical_commanding: dict[str, Any] | None = None,
    verbose: bool = False,
) -> Iterator[Flight]:
    """Both hosts up, the link between them, nothing run yet; everything stopped and removed after.
    ``paced`` (trajectory → time scale): the simulation at that pace while the AT server executes
    the trajectory, at ``time_scale`` otherwise (the probe sets it: :mod:`habitat_probe`), so that
    a fault struck at the start of that execution falls mid-motion in a flight otherwise flat out.
    ``verbose``: the habitat's ``up`` echoes its parts' output (``Habitat.up.output``, its last 400 lines).
    The ground database has the test people's accounts, and bob's password is in the flight's
    processes' environment (only a ground runner reads it), so a run approves with
    :data:`APPROVED_BY_BOB`."""
    with TwoHosts.create(ros_env) as hosts:
        db_url = f"sqlite:///{hosts.folder / 'audit.db'}"
        hosts.env = approver_env(db_url, hosts.env)
        credentials = make_link_credentials(hosts.folder / "link", [hosts.habitat.address, hosts.link.address], days=2)
        link_url = f"wss://{hosts.link.address}:{BRIDGE_PORT}"
        binding = write_ground_binding(
            hosts.folder, link_url, credentials, one_way_delay=delay, outage_budget=outage_budget
        )
        paces = [f"--pace={trajectory}={scale:g}" for trajectory, scale in (paced or {}).items()]
        probe = hosts.python(
            hosts.habitat, str(PROBE), *paces, *([f"--then={time_scale}"] if paces else []), ready=r"^READY probe"
        )
        habitat = start_habitat(
            hosts,
            credentials,
            binding,
            hosts.folder / "habitat-state",
            time_scale=time_scale,
            onboard=onboard,
            critical_commanding=critical_commanding,
            verbose=verbose,
        )
        link = hosts.start_link(target_port=BRIDGE_PORT, port=BRIDGE_PORT, delay=delay, options=link_options)
        yield Flight(hosts, habitat, probe, link, binding, db_url, credentials, time_scale)


def result_of(run: ManagedProcess, timeout: float = RUN_TIMEOUT_S) -> tuple[str, str]:
    """(run id, final status) from the runner's ``RESULT <status> run <id>`` line."""
    words = run.wait_for_line(r"^RESULT ", timeout).split()
    return words[3], words[1]


def commands(events: list[Event]) -> list[tuple[Event, Event | None]]:
    """Each COMMAND_SENT with the COMMAND_RESULT that answered it (None if none did)."""
    pairs: list[tuple[Event, Event | None]] = []
    for event in events:
        if event.kind is EventKind.COMMAND_SENT:
            pairs.append((event, None))
        elif event.kind is EventKind.COMMAND_RESULT:
            sent = next(
                i
                for i in range(len(pairs) - 1, -1, -1)
                if pairs[i][1] is None and pairs[i][0].instruction == event.instruction
            )
            pairs[sent] = (pairs[sent][0], event)
    return pairs


# ------------------------------------------------------------- what the IVA runs must show

DELAY = 1.3
#: Arm trajectory goals of each nominal step of the IVA procedure: one per planned waypoint segment
#: that moves the arm (the gripper's close and release move none): the ready pose and each look
#: one, a pull-out or a placement three. If the templates change, a clean run shows the new
#: numbers (every goal SUCCEEDED once).
IVA_ARM_GOALS_BY_STEP = {
    "prepare": 4,
    "remove_dirty": 3,
    "place_dirty": 3,
    "pick_clean": 5,
    "insert_clean": 3,
    "lock_clean": 0,
    "complete": 1,
}
#: Arm trajectory goals of one whole run, over its eleven executions (six motions and five looks).
IVA_ARM_GOALS = sum(IVA_ARM_GOALS_BY_STEP.values())


def nominal_commands(path: Path, *, to: str | None = None) -> list[str]:
    """The commands (their names, in order) a run of the procedure sends when nothing goes wrong:
    those of its nominal steps (none branches) up to and with step ``to`` (None: to the end), each
    call counting its sub-procedure's."""
    names: list[str] = []
    for step in load_procedure(path).steps:
        if step.contingency:
            continue
        for i in step.instructions:
            if isinstance(i, CommandInstruction):
                names.append(i.command)
            elif isinstance(i, CallInstruction):
                names += nominal_commands(path.parent / i.procedure)
        if step.id == to:
            return names
    if to is not None:
        raise ValueError(f"{path.name} has no nominal step {to!r}")
    return names


def arm_goals(to: str | None = None) -> int:
    """The arm trajectory goals of a run of the IVA procedure up to and with step ``to`` (None: all)."""
    steps = list(IVA_ARM_GOALS_BY_STEP)
    return sum(IVA_ARM_GOALS_BY_STEP[step] for step in steps[: steps.index(to) + 1 if to else None])


#: Commands of one run (adds, poses, plans, executes, the bay's inventory, locates, unlock, lock,
#: deletes), as the procedure and its look, locate, register calls write them.
IVA_COMMANDS = len(nominal_commands(PROCEDURE))
#: The first placement of a filter on the rack (step 3): the execution after the pull-out.
PLACE_DIRTY = "insert_and_release"
#: That step's id: a run ``--to`` it does what the pull-out needs, the pull-out and one motion after.
PLACE_DIRTY_STEP = "place_dirty"


def assert_flown_exactly_once(f: Flight, run_id: str, status: str, *, to: str | None = None) -> None:
    """The run (of the procedure up to and with step ``to``: ``--to``; None: all of it) completed;
    every command ran once on the habitat and was logged with its real outcome."""
    events = f.events(run_id)
    assert status == "completed", "\n".join(
        f"{e.instruction or '-'} {e.kind.value} {e.data}" for e in events[-12:]
    )  # the last events: the hold that stopped an unattended run, or the failure
    failed = [e for e in events if e.kind is EventKind.INSTRUCTION_FAILED]
    assert not failed, "\n".join(f"{e.instruction} failed: {e.data}" for e in failed)  # what went wrong, not just that
    expected = nominal_commands(PROCEDURE, to=to)
    sent = commands(events)
    logged = [s.data.to_json()["command"] for s, _ in sent]
    assert logged == expected, logged
    unanswered = [s.instruction for s, answer in sent if answer is None]
    assert not unanswered, f"commands without a logged outcome: {unanswered}"
    assert all(answer is not None and answer.data.to_json()["success"] for _, answer in sent)
    # The habitat's own record: each command executed once, and it succeeded.
    records = f.habitat.ledger_records()
    assert len(records) == len(expected), [(r["command_key"], r["state"]) for r in records]
    assert {r["state"] for r in records} == {"SUCCEEDED"}, [(r["command_key"], r["message"]) for r in records]
    executions = [r for r in records if r["service"].endswith("/execute_command")]
    assert len(executions) == expected.count("execute_plan")
    assert [r["service"].rsplit("/", 1)[-1] for r in records].count("execute_command") == logged.count("execute_plan")
    # What the arm did: every motion once, each carried out.
    goals = f.goals()
    assert len({goal for goal, _ in goals}) == len(goals) == arm_goals(to), goals
    assert {status for _, status in goals} == {4}, goals


def assert_in_flight(events: list[Event], trajectory: str, moment: datetime) -> None:
    """``moment`` (a fault) fell while the ground waited for the first execution of ``trajectory``."""
    sent, answer = next(
        (s, a)
        for s, a in commands(events)
        if s.data.to_json()["command"] == "execute_plan" and s.data.to_json()["args"]["trajectory"] == trajectory
    )
    assert answer is not None and sent.time < moment < answer.time, (sent.time, moment, answer and answer.time)


def start_from_console(
    page: Page, f: Flight, *, onboard: bool, approver: tuple[str, str] | None = None, own: tuple[str, str] | None = None
) -> str:
    """Start the IVA procedure, autonomous (``onboard``: on the habitat) from the signed-in console
    page; its run id once the page shows the run (every step waits on round trips of 2.6 s).
    ``approver`` (user, password): the second operator who approves, at this console, the commands
    the unit must carry approved (the start is first refused with the list of them); ``own``: the
    signed-in operator's account, tried as the approver first, which the console must refuse."""
    page.select_option("#start-procedure", PROCEDURE.name)
    page.select_option("#start-binding", f.binding.name)
    page.check("#start-form input[name=mode][value=autonomous]")
    page.set_checked("#start-onboard", onboard)
    page.check("#start-rehearsal")  # the shipped procedure, never released in this flight's database
    page.click("#start-button")
    if approver is not None:
        from playwright.sync_api import expect

        page.locator("#uplink-approval").wait_for(state="visible")
        for user, password in [own, approver] if own else [approver]:
            page.fill("#approver-user", user)
            page.fill("#approver-password", password)
            page.click("#approve-uplink")
            if (user, password) == own:
                expect(page.locator("#start-error")).to_contain_text(f"a second operator must approve, not {user}")
    page.wait_for_function(
        "() => document.querySelector('#run-id').textContent || document.querySelector('#start-error').textContent",
        timeout=180_000,
    )
    said = page.locator("#start-error").inner_text()
    assert not said, said
    return page.locator("#run-id").inner_text().strip()
