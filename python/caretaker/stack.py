"""``caretaker up DEPLOYMENT``: a robot side, its command ledger and its rosbridge server from one file.

The robot side (simulation, planner, AT server), the command ledger and the rosbridge server run
as separate OS processes, as they would on a habitat host that the ground reaches over a link.
The stack starts them in the order of :data:`PARTS` and waits for each one's ``READY`` line.
Which parts there are is data: a part is one :class:`Part` entry saying how its command line is
made from the deployment (and whether the deployment wants it), so adding a process is adding
an entry. A deployment with a ``link:`` section also gets ``caretaker link`` in front of the
bridge, so a ground team can rehearse over the link they will fly with on one host.

When a part dies, ``caretaker up`` restarts it, as a robot's process supervisor would: the AT
server comes back with its instances (``--state-file`` in the stack's state folder), the ledger
with its memory (``--state-dir`` there too: a command sent before the restart is still executed
at most once, and its outcome is still known), the planner and rosbridge come back empty
(rosbridge and the link on the ports they had, even if picked with port 0), and a procedure
carries on. The simulation is the world itself: if it dies, or a part keeps dying (more than
:data:`RESPAWN_LIMIT` times in :data:`RESPAWN_WINDOW_S`), everything stops, so the stack never
leaves a half-running robot behind. ``caretaker demo`` restarts nothing: a demo that needed a
restart has failed.
"""

from __future__ import annotations

import argparse
import logging
import os
import shutil
import signal
import sys
import tempfile
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from bridge.rosbridge.limits import Limits
from bridge.rosbridge.limits import option as limit_option
from caretaker.deployment import Deployment, load_deployment
from caretaker.processes import ManagedProcess, ProcessFailed, caretaker
from caretaker.terminal import TerminalLines
from datafile import DataFileError
from procedure_language.binding import read_binding
from rosbridge_wire.light_time import LightTime
from sim import cabin_knobs

__all__ = ["PARTS", "Part", "PartEcho", "Stack", "StackFailed", "StackRun", "stack_options", "up_main"]

log = logging.getLogger("caretaker.stack")

#: A part that dies more often than this within RESPAWN_WINDOW_S is not restarted again.
RESPAWN_LIMIT = 3
RESPAWN_WINDOW_S = 60.0


@dataclass
class StackRun:
    """What one running stack adds to its deployment: overrides, its state folder, the bridge port."""

    time_scale: float
    bridge_address: str
    bridge_port: int  # 0 until the bridge picked one, when the deployment says 0
    state_dir: Path
    link_port: int = 0  # the emulated link's listening port (0 until it picked one, if asked to)
    displace: int | None = None  # the seed of a displaced world (sim --displace), None: as the scene says
    cabin: dict[str, float] = field(default_factory=dict)  # the cabin's air knobs (sim/cabin_knobs.py) given


@dataclass(frozen=True)
class Part:
    """One process of a robot side: its name, and its ``caretaker`` command line for a deployment.

    ``world``: the part *is* the world (the simulation); it is never restarted, and its death
    ends the stack. ``wanted``: whether a deployment has this part (default: every one does).
    """

    name: str
    command: Callable[[Deployment, StackRun], list[str]]
    world: bool = False
    wanted: Callable[[Deployment], bool] = lambda deployment: True


def _robot_options(deployment: Deployment) -> list[str]:
    options = ["--robot", str(deployment.robot), "--templates", str(deployment.templates)]
    if deployment.robots is not None:
        options += ["--robots", str(deployment.robots)]
    if deployment.namespace:
        options += ["--namespace", deployment.namespace]
    return options


def _sim(deployment: Deployment, run: StackRun) -> list[str]:
    args = ["sim", "--scene", str(deployment.scene), "--time-scale", str(run.time_scale)]
    if deployment.namespace:
        args += ["--namespace", deployment.namespace]
    if deployment.capture_dir is not None:
        args += ["--capture-dir", str(deployment.capture_dir)]
    if run.displace is not None:
        args += ["--displace", str(run.displace)]
    return args + cabin_knobs.command_line(run.cabin)


def _perception(deployment: Deployment, run: StackRun) -> list[str]:
    return ["perception", *(["--namespace", deployment.namespace] if deployment.namespace else [])]


def _planner(deployment: Deployment, run: StackRun) -> list[str]:
    return ["planner", *_robot_options(deployment)]


def _at_server(deployment: Deployment, run: StackRun) -> list[str]:
    return ["at-server", *_robot_options(deployment), "--state-file", str(run.state_dir / "at_server.json")]


def _ledger(deployment: Deployment, run: StackRun) -> list[str]:
    ledger = deployment.ledger
    args = [
        "ledger",
        "--state-dir",
        str(run.state_dir / "ledger"),
        "--retain-hours",
        str(ledger.retain_hours),
        "--default-timeout",
        str(ledger.default_timeout),
    ]
    namespace = deployment.namespace
    if namespace:  # robots sharing a ROS graph each have their own ledger (bindings: ledger_namespace)
        args += ["--ros-args", "-r", f"__ns:={namespace}"]
        for service in ("execute", "outcome"):
            args += ["-r", f"/command_ledger/{service}:={namespace}/command_ledger/{service}"]
    return args


def _link(deployment: Deployment, run: StackRun) -> list[str]:
    link = deployment.link
    assert link is not None  # wanted only then
    host, port = link.listen
    return [
        "link",
        "--listen",
        f"{_host(host)}:{run.link_port or port}",
        "--to",
        f"{_host(run.bridge_address)}:{run.bridge_port}",
        "--control",
        str(run.state_dir / "link.sock"),
        *link.options(),
    ]


def _host(address: str) -> str:
    """An address as the host part of HOST:PORT (IPv6 in brackets)."""
    return f"[{address}]" if ":" in address else address


def _bridge(deployment: Deployment, run: StackRun) -> list[str]:
    bridge = deployment.bridge
    # Halts are called rarely and must act at once: their clients are matched before they are needed.
    args = ["bridge", "--address", run.bridge_address, "--port", str(run.bridge_port), "--ready-services", "*/halt"]
    for option, path in (
        ("--certfile", bridge.certfile),
        ("--keyfile", bridge.keyfile),
        ("--auth-secret-file", bridge.auth_secret_file),
    ):
        if path is not None:
            args += [option, str(path)]
    return args + _light_time_limits(deployment)


def _light_time_limits(deployment: Deployment) -> list[str]:
    """The bridge's handshake, login and keepalive limits, never shorter than the longest light
    time of the bindings it serves (a ground 45 s away needs minutes to open a connection)."""
    delay = max((read_binding(path).link.one_way_delay for path in deployment.bindings), default=0.0)
    defaults = Limits()
    return [
        argument
        for name, least in LightTime(delay).bridge_limits().items()
        if least > getattr(defaults, name)
        for argument in (limit_option(name), f"{least:g}")
    ]


def _onboard(deployment: Deployment, run: StackRun) -> list[str]:
    args = [
        "onboard",
        "--bridge",
        f"{deployment.bridge.scheme}://{_host(run.bridge_address)}:{run.bridge_port}",
        "--state-dir",
        str(run.state_dir / "onboard"),
    ]
    for binding in deployment.bindings:
        args += ["--binding", str(binding)]
    return args


#: The parts of a robot side, in the order they start (each waits for the ones before).
PARTS: tuple[Part, ...] = (
    Part("sim", _sim, world=True),
    Part("perception", _perception),
    Part("planner", _planner),
    Part("at-server", _at_server),
    Part("ledger", _ledger),
    Part("bridge", _bridge),
    Part("link", _link, wanted=lambda deployment: deployment.link is not None),
    Part("onboard", _onboard, wanted=lambda deployment: deployment.onboard),
)


class StackFailed(RuntimeError):
    """A part of the stack did not start, or died while running."""


#: How a part prints a security event (a refused unit or action): shown even when parts are not echoed.
SECURITY_LINE = "SECURITY "


class PartEcho:
    """Echoes the parts' output, each line after its part's name (``[at-server] ...``): every line
    (``everything``), or only the security events (:data:`SECURITY_LINE`), which are always shown.

    The parts print from their own reader threads, so their lines interleave: the name says who
    wrote each, and one column as wide as the longest name keeps the lines themselves aligned.
    """

    def __init__(self, names: Sequence[str], out: TerminalLines, *, everything: bool) -> None:
        self.out = out
        self.everything = everything
        self.width = max((len(name) for name in names), default=0) + 2  # the brackets

    def __call__(self, name: str, line: str) -> None:
        """``ManagedProcess``'s ``on_line``: print one line of part ``name``, if it is to be shown."""
        if self.everything or line.startswith(SECURITY_LINE):
            self.out.say(f"{f'[{name}]':<{self.width}} {line}")


class Stack:
    """The parts of one deployment as child processes.

    Start it from the main thread: children are tied to the thread that started them and are
    killed by the kernel if it goes away (see caretaker.processes).
    """

    def __init__(
        self,
        deployment: Deployment,
        *,
        time_scale: float | None = None,
        bridge_address: str | None = None,
        bridge_port: int | None = None,
        displace: int | None = None,
        cabin: Mapping[str, float] | None = None,
        parts: Sequence[str] | None = None,
        env: dict[str, str] | None = None,
        ready_timeout: float = 120.0,
        echo: bool = False,
        respawn: bool = False,
    ) -> None:
        """Overrides (``time_scale``, ``bridge_*``, ``displace``) replace the deployment's values; ``cabin``
        sets the simulated cabin's air (sim/cabin_knobs.py, by parameter name; the simulation refuses a value
        out of range); ``parts``
        names a subset of :data:`PARTS` to run (tests); ``echo``: print every line the parts print,
        after the part's name (:class:`PartEcho`); ``respawn``: :meth:`supervise` restarts parts that
        die (all but the world).

        Raises:
            StackFailed: ``parts`` names a part that does not exist.
        """
        self.deployment = deployment
        unknown = sorted(set(parts or ()) - {p.name for p in PARTS})
        if unknown:
            raise StackFailed(f"unknown parts {unknown}; parts are {', '.join(p.name for p in PARTS)}")
        self.parts = [p for p in PARTS if (parts is None or p.name in parts) and p.wanted(deployment)]
        self.env = dict(os.environ if env is None else env)
        self.env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        if deployment.domain_id is not None:
            self.env["ROS_DOMAIN_ID"] = str(deployment.domain_id)
        # A new stack is a new world: without a state folder of the deployment's, instances are
        # kept in a folder of this stack's own and go with it.
        self._own_state_dir = deployment.state_dir is None
        state_dir = (
            Path(tempfile.mkdtemp(prefix=f"caretaker-{deployment.name}-"))
            if deployment.state_dir is None
            else deployment.state_dir
        )
        state_dir.mkdir(parents=True, exist_ok=True)
        self.run = StackRun(
            time_scale=deployment.time_scale if time_scale is None else time_scale,
            bridge_address=deployment.bridge.address if bridge_address is None else bridge_address,
            bridge_port=deployment.bridge.port if bridge_port is None else bridge_port,
            state_dir=state_dir,
            displace=deployment.displace if displace is None else displace,
            cabin=dict(cabin or {}),
        )
        self.ready_timeout = ready_timeout
        self.respawn = respawn
        self.processes: dict[str, ManagedProcess] = {}
        self.ready_lines: dict[str, str] = {}
        self.restarts: dict[str, deque[float]] = {p.name: deque() for p in self.parts}
        self._exited = threading.Event()
        self.terminal = TerminalLines()  # the parts' echoed lines come from their reader threads
        self._echo = PartEcho([p.name for p in self.parts], self.terminal, everything=echo)

    @property
    def bridge_url(self) -> str:
        """The rosbridge server's URL (its actual port once it started)."""
        return f"{self.deployment.bridge.scheme}://{_host(self.run.bridge_address)}:{self.run.bridge_port}"

    @property
    def url(self) -> str:
        """Where ground clients connect: the emulated link when the stack has one, else the bridge."""
        link = self.deployment.link
        if link is None or not any(p.name == "link" for p in self.parts):
            return self.bridge_url
        return f"{self.deployment.bridge.scheme}://{_host(link.listen[0])}:{self.run.link_port or link.listen[1]}"

    def start(self) -> None:
        """Start every part in order and wait until each serves.

        Raises:
            StackFailed: a part exited or did not become ready; everything started is stopped.
        """
        try:
            for part in self.parts:
                self.start_part(part.name)
        except (ProcessFailed, DataFileError) as exc:
            self.stop()
            raise StackFailed(str(exc)) from None

    def part(self, name: str) -> Part:
        return next(p for p in self.parts if p.name == name)

    def start_part(self, name: str) -> ManagedProcess:
        """Start one part (again) and wait for its READY line.

        Raises:
            ProcessFailed: it exited or did not become ready in time.
        """
        started = time.monotonic()
        proc = caretaker(
            *self.part(name).command(self.deployment, self.run), env=self.env, name=name, on_line=self._echo
        )
        self.processes[name] = proc
        threading.Thread(target=self._await_exit, args=(proc,), name=f"{name}-exit", daemon=True).start()
        line = proc.wait_ready(self.ready_timeout)
        self.ready_lines[name] = line
        if name == "bridge" and self.run.bridge_port == 0:
            # Keep the port the bridge picked, so a restart serves the same URL.
            self.run.bridge_port = int(line.rsplit(":", 1)[-1])
        if name == "link" and self.run.link_port == 0:  # READY link HOST:PORT -> HOST:PORT (...)
            self.run.link_port = int(line.split()[2].rsplit(":", 1)[-1])
        log.info("%s ready in %.1f s: %s", name, time.monotonic() - started, line)
        return proc

    def _await_exit(self, proc: ManagedProcess) -> None:
        proc.proc.wait()
        self._exited.set()

    def dead_parts(self) -> list[str]:
        """Names of the parts that are no longer running."""
        return [name for name, proc in self.processes.items() if not proc.running]

    def supervise(self, stop: threading.Event) -> list[str]:
        """Run until ``stop`` is set (returns []) or a part dies that is not restarted (returns
        the dead parts). Call from the thread that started the stack: restarted children are
        tied to the thread that starts them (see caretaker.processes).

        ``stop`` must also set :meth:`wake`, so that a signal handler ends the wait at once.
        """
        while not stop.is_set():
            self._exited.wait()
            self._exited.clear()
            if stop.is_set():
                break
            for name in self.dead_parts():
                if not self._may_restart(name):
                    return self.dead_parts()
                code = self.processes[name].stop()
                self.terminal.say(f"{name} died (exit {code}); restarting it")
                try:
                    self.start_part(name)
                except ProcessFailed as exc:
                    print(f"{name} did not come back: {exc}", file=sys.stderr, flush=True)
                    return self.dead_parts()
                self.terminal.say(f"restarted {name}: {self.ready_lines[name]}")
        return []

    def wake(self) -> None:
        """End a :meth:`supervise` wait (from a signal handler)."""
        self._exited.set()

    def _may_restart(self, name: str) -> bool:
        if not self.respawn or self.part(name).world:
            return False
        now = time.monotonic()
        recent = self.restarts[name]
        while recent and now - recent[0] > RESPAWN_WINDOW_S:
            recent.popleft()
        if len(recent) >= RESPAWN_LIMIT:
            print(
                f"{name} died {RESPAWN_LIMIT + 1} times within {RESPAWN_WINDOW_S:.0f} s: not restarting it again",
                file=sys.stderr,
            )
            return False
        recent.append(now)
        return True

    def stop(self) -> None:
        """Stop every part, last started first, and remove the stack's own folder. Idempotent."""
        for part in reversed(self.parts):
            proc = self.processes.get(part.name)
            if proc is not None:
                log.info("%s stopped (exit %s)", part.name, proc.stop())
        if self._own_state_dir:
            shutil.rmtree(self.run.state_dir, ignore_errors=True)


def stack_options(prog: str) -> argparse.ArgumentParser:
    """The options ``up`` and ``demo`` share: the deployment and what a run may override."""
    parser = argparse.ArgumentParser(prog=prog)
    parser.add_argument(
        "deployment", metavar="DEPLOYMENT", help="a deployment file, or the name of a shipped one (iva, eva)"
    )
    parser.add_argument(
        "--time-scale",
        type=float,
        help="simulation speed: 1 = real time, 0 = as fast as possible (default: the deployment's)",
    )
    parser.add_argument("--bridge-address", help="address the rosbridge server binds (default: the deployment's)")
    parser.add_argument(
        "--bridge-port", type=int, help="rosbridge port; 0 picks a free one (default: the deployment's)"
    )
    parser.add_argument(
        "--displace",
        type=int,
        metavar="SEED",
        help="a world not where the scene file puts it: the slot bodies and targets moved by a random offset of"
        " this seed, found only by perception (default: the deployment's displace, else none)",
    )
    cabin_knobs.add_options(parser)  # the simulated cabin's CO2, for a demonstration of an anomaly
    parser.add_argument("--verbose", "-v", action="store_true", help="echo every part's output")
    return parser


def _run_until_signal(stack: Stack) -> int:
    """Supervise until Ctrl-C/SIGTERM (exit 0) or a part dies for good (exit 1), then stop the stack."""
    stop = threading.Event()

    def on_signal(*_: object) -> None:
        stop.set()
        stack.wake()

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, on_signal)
    dead = stack.supervise(stop)
    stack.stop()
    if dead:
        for name in dead:
            print(f"caretaker up: {name} died; its last output:\n{stack.processes[name].tail(30)}", file=sys.stderr)
        return 1
    return 0


def up_main(argv: list[str] | None = None) -> int:
    """``caretaker up DEPLOYMENT``: run the robot side and the bridge until Ctrl-C."""
    args = stack_options("caretaker up").parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        deployment = load_deployment(args.deployment)
        stack = Stack(
            deployment,
            time_scale=args.time_scale,
            bridge_address=args.bridge_address,
            bridge_port=args.bridge_port,
            displace=args.displace,
            cabin=cabin_knobs.given(args),
            echo=args.verbose,
            respawn=True,
        )
        stack.start()
    except (DataFileError, StackFailed) as exc:
        print(f"caretaker up: {exc}", file=sys.stderr)
        return 1
    for name, line in stack.ready_lines.items():
        stack.terminal.say(f"{name:10} {line}")
    stack.terminal.say(f"READY stack {deployment.name} {stack.url}")
    return _run_until_signal(stack)
