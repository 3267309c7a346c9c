"""``caretaker demo anomaly``: an alarm answered end to end, from the assistant's proposal to the cleared alarm.

The paper's future work, flown: the IVA habitat (``caretaker up`` of the IVA robot side with the
onboard executive, behind ``caretaker link`` at Gateway's 1.3 s one way, wss:// and the link's
secret), a ground console on a ground database (``caretaker serve``), and the reference agent
(``caretaker agent --reference``, an MCP client that uses only an agent's tools). When all are up,
the cabin's CO2 is raised to just under its yellow limit and its chemistry sped up (the
simulator's ``cabin_start_ppco2`` and ``cabin_chemistry_scale``, set over ROS as an operator would
rehearse a fault): the saturated filter in the CDRA cabinet lets it rise past yellow. The agent
sees the alarm, finds the released procedure that responds to it, and proposes it; the demo's
operator accepts it on the console, scripted as the demo answers records elsewhere, with the
demo's second operator approving the hazardous unlock before the unit goes up (one operator
action); the habitat runs the filter change by itself; the agent follows the run and says when
the CO2 is within its limits again.

The demo prints the timeline (alarm, proposal, acceptance, start, completion, cleared) and exits 0
only if the run completed, the world is as the IVA demo's checks say (the dirty filter on the rack,
the clean one locked in the cabinet) and the CO2 came back within its limits. Everything it writes
is in ``var/anomaly/RUN/`` (``--reports DIR``: ``DIR/RUN/``): the ground database (unless ``--db``
names one), the generated binding and deployment, the habitat's state; the link's credentials in
``var/anomaly/link/`` (``DIR/link/``) are made once and kept.
"""

from __future__ import annotations

import argparse
import http.cookiejar
import json
import os
import re
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Callable, Mapping
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import yaml

from caretaker.certs import FILES, make_link_credentials
from caretaker.deployment import load_deployment
from caretaker.processes import REPO, ManagedProcess, ProcessFailed, caretaker
from caretaker.stack import Stack, StackFailed
from caretaker.world_checks import watch_world
from console.accounts import AccountStore
from pride.approvals import APPROVER_PASSWORD_ENV
from records.agent_tokens import TokenStore
from rosbridge_wire.client import Endpoint
from sim.scene import load_scene
from sim.sim_parameters import SimParametersRefused, set_sim_parameters

__all__ = ["anomaly_demo"]

IVA_DEPLOYMENT = REPO / "deployments" / "iva.yaml"  # its demo's world checks
IVA_PROCEDURE = REPO / "procedures" / "iva_cdra_filter_replacement.xml"
GROUND_BINDING = REPO / "sysrep" / "bindings" / "iva-ground.yaml"
ONE_WAY_DELAY = 1.3  # s, Earth–Gateway
#: The fault: the cabin just under its yellow limit (4.0 mmHg) and its chemistry 20 times sim time, so the
#: spent filter lets it pass yellow within seconds, and a clean filter locked in brings it back within a minute.
FAULT = {"cabin_start_ppco2": 3.98, "cabin_chemistry_scale": 20.0}
OPERATOR, APPROVER, AGENT = "demo", "demo-approver", "daphne"
#: Seconds the whole loop may take from the fault on (the run itself is about a minute at 1x).
WITHIN_S = 900.0
EVENTS = ("alarm", "proposal", "acceptance", "start", "completion", "cleared")


def anomaly_demo(args: argparse.Namespace) -> int:
    """Run the demo (``args``: ``caretaker demo``'s stack options); 0 only if every check holds."""
    home = Path(args.reports) if args.reports else REPO / "var" / "anomaly"
    folder = home / datetime.now(UTC).strftime("%Y%m%dT%H%M%SZ")
    folder.mkdir(parents=True)
    credentials = _credentials(home / "link")
    binding = _ground_binding(folder / "bindings", credentials, "wss://127.0.0.1:9")  # its URL: once the link is up
    deployment = load_deployment(_habitat_deployment(folder, credentials, binding))
    db_url = args.db or f"sqlite:///{folder / 'ground.db'}"
    passwords = _accounts(db_url)
    stack = Stack(deployment, time_scale=args.time_scale, echo=args.verbose)
    print(f"Starting the IVA habitat behind a {ONE_WAY_DELAY} s link: {', '.join(p.name for p in stack.parts)}")
    try:
        stack.start()
    except StackFailed as exc:
        print(f"caretaker demo anomaly: {exc}")
        return 1
    started: list[ManagedProcess] = []
    try:
        link_url = stack.url  # the link's: where the ground connects
        _ground_binding(folder / "bindings", credentials, link_url)
        # TMPDIR: the log of the runner the console starts (kept after it ends) goes with the demo's report
        env = {**stack.env, "CARETAKER_DB": db_url, "TMPDIR": str(folder)}
        if not _release(db_url, passwords, env):
            return 1
        console = caretaker(
            "serve", "--port", "0", "--db", db_url, "--bindings", str(binding.parent),
            "--deployments", str(deployment.path), "--rosbridge", link_url, env=env, name="serve",
        )  # fmt: skip
        started.append(console)
        console_url = console.wait_ready(120).split()[-1]
        habitat = Endpoint(  # the habitat's own bridge, not across the link: the demo's eyes on the world
            stack.bridge_url,
            ca_file=credentials["ca.pem"],
            secret=credentials["rosbridge.secret"].read_text(encoding="utf-8").strip(),
        )
        checks = load_deployment(IVA_DEPLOYMENT).demo
        assert checks is not None
        told: list[str] = []  # the agent's TIMELINE lines, as it prints them
        with watch_world(checks.checks, habitat, deployment.namespace, load_scene(deployment.scene)) as world:
            agent = caretaker(
                "agent", "--reference", "--robot", "iva", "--within", str(WITHIN_S), "--db", db_url,
                "--bindings", str(binding.parent), "--rosbridge", link_url, "--watch-every", "1",
                env={**env, "CARETAKER_AGENT_TOKEN": passwords["token"]}, name="agent", on_line=_told(told),
            )  # fmt: skip
            started.append(agent)
            set_sim_parameters(FAULT)  # over ROS in the habitat's domain: its bridge lets nobody set parameters
            fault_at = time.time()
            fault = f"{FAULT['cabin_start_ppco2']} mmHg, its chemistry x{FAULT['cabin_chemistry_scale']:g}"
            print(f"[{_stamp()}] the cabin's CO2 set to {fault}", flush=True)
            run_id = _operator_accepts(console_url, passwords, agent)
            code = _agent_ends(agent) if run_id else agent.proc.wait(timeout=WITHIN_S)
            timeline = _timeline(told)
            verdicts = world.judge(db_url, run_id) if run_id else []
        return _verdict(code, timeline, verdicts, fault_at, run_id, db_url, agent)
    except (ProcessFailed, SimParametersRefused) as exc:
        print(f"caretaker demo anomaly: {exc}")
        return 1
    finally:
        for process in reversed(started):
            process.stop()
        stack.stop()


def _credentials(folder: Path) -> dict[str, Path]:
    """The link's CA, bridge certificate and secret for 127.0.0.1, made at the first demo and kept."""
    paths = {name: folder / name for name in FILES}
    if all(path.exists() for path in paths.values()):
        return paths
    return make_link_credentials(folder, ["127.0.0.1"], days=365, force=True)


def _ground_binding(folder: Path, credentials: Mapping[str, Path], url: str) -> Path:
    """The shipped ground binding of the IVA robot with this demo's link, credentials and ``url``."""
    data = yaml.safe_load(GROUND_BINDING.read_text(encoding="utf-8"))
    data["rosbridge"] = url
    data["link"]["one_way_delay"] = ONE_WAY_DELAY
    data["security"] = {"ca_file": str(credentials["ca.pem"]), "secret_file": str(credentials["rosbridge.secret"])}
    for system in data["systems"]:
        system["sysrep"] = str((GROUND_BINDING.parent / system["sysrep"]).resolve())
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / GROUND_BINDING.name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def _habitat_deployment(folder: Path, credentials: Mapping[str, Path], binding: Path) -> Path:
    """The IVA habitat: the shipped habitat deployment on loopback, with the onboard executive, the
    emulated link in front of its bridge, and this demo's state folder, credentials and binding."""
    data = yaml.safe_load((REPO / "deployments" / "iva-habitat.yaml").read_text(encoding="utf-8"))
    base = REPO / "deployments"
    for key in ("scene", "robot", "templates", "robots"):
        data[key] = str((base / data[key]).resolve())
    data["bridge"] = {
        "address": "127.0.0.1",
        "port": 0,
        "certfile": str(credentials["bridge.pem"]),
        "keyfile": str(credentials["bridge.key"]),
        "auth_secret_file": str(credentials["rosbridge.secret"]),
    }
    data.update(
        state_dir=str(folder / "habitat"),
        bindings=[str(binding)],
        onboard=True,
        link={"listen": "127.0.0.1:0", "delay": ONE_WAY_DELAY},
    )
    path = folder / "iva-habitat.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def _accounts(db_url: str) -> dict[str, str]:
    """The demo's operator, its second operator and the agent (with a token): their secrets."""
    store = AccountStore(db_url)
    try:
        secrets = {}
        for user, name in ((OPERATOR, "Demo operator"), (APPROVER, "Demo second operator (approves)")):
            secrets[user] = os.urandom(12).hex()
            store.add(user, "operator", secrets[user], name=name)
        store.add(AGENT, "agent", None, name="Reference agent")
        secrets["token"] = TokenStore(store.engine).issue(AGENT, None).token
    finally:
        store.close()
    return secrets


def _release(db_url: str, passwords: Mapping[str, str], env: dict[str, str]) -> bool:
    """Release the IVA procedure (the operator asks, the second operator releases), as a team's pipeline would."""
    release = caretaker(
        "release", str(IVA_PROCEDURE), "--user", OPERATOR, "--approver", APPROVER, "--db", db_url,
        env={**env, "CARETAKER_PASSWORD": passwords[OPERATOR], APPROVER_PASSWORD_ENV: passwords[APPROVER]},
        name="release",
    )  # fmt: skip
    release.proc.wait()
    release.stop()
    if release.proc.returncode != 0:
        print(f"caretaker demo anomaly: the release failed:\n{release.tail()}")
        return False
    return True


class _Console:
    """The console's JSON API as a browser uses it: a session cookie, the CSRF token on changes."""

    def __init__(self, url: str) -> None:
        self.url = url
        self._opener = urllib.request.build_opener(urllib.request.HTTPCookieProcessor(http.cookiejar.CookieJar()))
        self._csrf = ""

    def request(self, method: str, path: str, body: Any = None) -> tuple[int, Any]:
        data = None if body is None else json.dumps(body).encode()
        headers = {"Content-Type": "application/json", "X-CSRF-Token": self._csrf}
        sent = urllib.request.Request(self.url + path, data=data, method=method, headers=headers)
        try:
            with self._opener.open(sent, timeout=120) as answer:
                return answer.status, json.loads(answer.read() or b"{}")
        except urllib.error.HTTPError as refused:
            return refused.code, json.loads(refused.read() or b"{}")

    def sign_in(self, user: str, password: str) -> None:
        status, session = self.request("POST", "/api/session", {"user": user, "password": password})
        if status != 200:
            raise ProcessFailed(f"the demo operator could not sign in to the console: {session}")
        self._csrf = session["csrf"]


def _operator_accepts(console_url: str, passwords: Mapping[str, str], agent: ManagedProcess) -> str | None:
    """The demo's operator: sign in, wait for the agent's proposal, accept it to run on the habitat
    with the second operator's approval; the run's id (None if the agent ended first)."""
    console = _Console(console_url)
    console.sign_in(OPERATOR, passwords[OPERATOR])
    deadline = time.monotonic() + WITHIN_S
    while time.monotonic() < deadline and agent.proc.poll() is None:
        _, listed = console.request("GET", "/api/proposals")
        waiting = [p for p in listed.get("proposals", []) if p["state"] == "open"]
        if waiting:
            proposal = waiting[0]
            print(f"[{_stamp()}] the operator reads proposal {proposal['id']}: “{proposal['reason']}”", flush=True)
            body = {
                "mode": "autonomous",
                "onboard": True,
                "confirm_manual": True,  # nobody is on the habitat to confirm them
                "approver": APPROVER,
                "approver_password": passwords[APPROVER],
            }
            status, accepted = console.request("POST", f"/api/proposals/{proposal['id']}/accept", body)
            if status != 201:
                print(f"caretaker demo anomaly: the acceptance was refused ({status}): {accepted}")
                return None
            return str(accepted["run_id"])
        time.sleep(0.5)  # as an operator glances at the list: the console pushes no proposals
    return None


def _agent_ends(agent: ManagedProcess) -> int | None:
    """The agent's exit code once the alarm cleared or the agent gave up; None (the agent stopped)
    when the run waits for an operator first: the demo's operator only accepts proposals, so a run
    that holds would wait for the whole of :data:`WITHIN_S` for an answer that never comes."""
    try:
        line = agent.wait_for_line(r"^TIMELINE (cleared|waiting) ", WITHIN_S)
    except ProcessFailed:
        if agent.proc.poll() is None:
            raise  # neither ended nor cleared in the time given
        return agent.proc.returncode
    if line.startswith("TIMELINE waiting "):
        print(f"caretaker demo anomaly: {line.split(' ', 3)[3]}; the demo's operator only accepts proposals")
        agent.stop()
        return None
    return agent.proc.wait(timeout=60)  # it exits as soon as it said so


def _told(lines: list[str]) -> Callable[[str, str], None]:
    """Keep and show the agent's TIMELINE lines as it prints them (the rest stays in its output)."""

    def heard(_name: str, line: str) -> None:
        if line.startswith("TIMELINE "):
            lines.append(line)
            sys.stdout.write(f"  agent: {line.removeprefix('TIMELINE ')}\n")
            sys.stdout.flush()

    return heard


def _timeline(lines: list[str]) -> dict[str, datetime]:
    """The agent's TIMELINE lines: event -> when."""
    found: dict[str, datetime] = {}
    for line in lines:
        match = re.match(r"TIMELINE (\w+) (\S+) ", line)
        if match and match[1] in EVENTS:
            found.setdefault(match[1], datetime.fromisoformat(match[2]))
    return found


def _verdict(
    code: int | None,
    timeline: dict[str, datetime],
    verdicts: list[Any],
    fault_at: float,
    run_id: str | None,
    db_url: str,
    agent: ManagedProcess,
) -> int:
    alarm = timeline.get("alarm")
    print("Timeline (s after the alarm):")
    for event in EVENTS:
        when = timeline.get(event)
        shown = f"{(when - alarm).total_seconds():7.1f}" if when and alarm else "      -"
        print(f"  {shown}  {event}")
    for verdict in verdicts:
        sys.stdout.write(f"  {'verified' if verdict.holds else 'WRONG'}: {verdict.words}\n")
    missing = [event for event in EVENTS if event not in timeline]
    why = [f"wrong: {verdict.words}" for verdict in verdicts if not verdict.holds]
    if code != 0:
        why.insert(0, f"the agent exited {code}")
    if missing:
        why.append(f"the timeline lacks {', '.join(missing)}")
    if not verdicts:
        why.append("the world was not checked")
    if alarm is not None and "cleared" in timeline:
        cleared = (timeline["cleared"] - alarm).total_seconds()
        print(f"  alarm to cleared: {cleared:.1f} s; operator actions: 1 (the acceptance)")
        print(f"  the fault to the alarm: {alarm.timestamp() - fault_at:.1f} s")
    if why:  # said last, after the agent's own account, where a reader of a cut log still sees it
        print(f"the agent's last lines:\n{agent.tail()}")
        print(f"caretaker demo anomaly: the loop did not close: {'; '.join(why)}")
        return 1
    print(f"anomaly demo complete; run {run_id}; ground database {db_url}")
    return 0


def _stamp() -> str:
    return datetime.now(UTC).strftime("%H:%M:%S")
