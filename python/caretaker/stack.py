"""``caretaker up`` and ``caretaker demo``: the whole system from one command.

The robot side (simulation, planner, AT server) and the rosbridge server run as separate OS
processes, as they would in a deployment where the robot and the ground are apart. The stack
starts them in dependency order and waits for each one's ``READY`` line.

When a part dies, ``caretaker up`` restarts it, as a robot's process supervisor would: the AT
server comes back with its instances (``--state-file`` in the stack's own folder), the planner
and rosbridge come back empty, and a procedure carries on through its contingency steps. The
simulation is the world itself: if it dies, or a part keeps dying (more than
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
from dataclasses import dataclass, field
from pathlib import Path

from caretaker.processes import REPO, ManagedProcess, ProcessFailed, caretaker

__all__ = ["SCENARIOS", "Scenario", "Stack", "StackFailed", "demo_main", "up_main"]

log = logging.getLogger("caretaker.stack")


@dataclass(frozen=True)
class Scenario:
    """What a scene needs: the robot config it runs, and the demo procedure that goes with it."""

    scene: str
    robot: str
    procedure: Path
    binding: Path
    inputs: dict[str, str] = field(default_factory=dict)


SCENARIOS: dict[str, Scenario] = {
    "iva": Scenario(
        scene="iva",
        robot="ur10",
        procedure=REPO / "procedures" / "iva_cdra_filter_replacement.xml",
        binding=REPO / "sysrep" / "bindings" / "iva.yaml",
    ),
    "eva": Scenario(
        scene="eva",
        robot="eva_arm",
        procedure=REPO / "procedures" / "eva_inspection.xml",
        binding=REPO / "sysrep" / "bindings" / "eva.yaml",
    ),
}


#: A part that dies more often than this within RESPAWN_WINDOW_S is not restarted again.
RESPAWN_LIMIT = 3
RESPAWN_WINDOW_S = 60.0
#: The part that is the world: a new simulation is a new world, so it is never restarted.
WORLD = "sim"


class StackFailed(RuntimeError):
    """A part of the stack did not start, or died while running."""


class Stack:
    """The robot side and the rosbridge server of one scenario, as child processes.

    Start it from the main thread: children are tied to the thread that started them and are
    killed by the kernel if it goes away (see caretaker.processes).
    """

    def __init__(
        self,
        scenario: Scenario,
        *,
        time_scale: float = 1.0,
        bridge_address: str = "127.0.0.1",
        bridge_port: int = 9090,
        env: dict[str, str] | None = None,
        ready_timeout: float = 120.0,
        echo: bool = False,
        respawn: bool = False,
    ) -> None:
        """``respawn``: :meth:`supervise` restarts parts that die (all but the simulation)."""
        self.scenario = scenario
        self.env = dict(os.environ if env is None else env)
        self.env.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        self.ready_timeout = ready_timeout
        self.echo = echo
        self.respawn = respawn
        at_server = ("at-server", "--robot", scenario.robot)
        if respawn:
            # The stack's own folder: a new stack is a new world and must not restore old instances.
            self.state_dir: Path | None = Path(tempfile.mkdtemp(prefix="caretaker-up-"))
            at_server += ("--state-file", str(self.state_dir / "at_server.json"))
        else:
            self.state_dir = None
        self.parts: dict[str, tuple[str, ...]] = {
            WORLD: ("sim", "--scene", scenario.scene, "--time-scale", str(time_scale)),
            "planner": ("planner", "--robot", scenario.robot),
            "at-server": at_server,
            "bridge": ("bridge", "--address", bridge_address, "--port", str(bridge_port)),
        }
        self.processes: dict[str, ManagedProcess] = {}
        self.ready_lines: dict[str, str] = {}
        self.restarts: dict[str, deque[float]] = {name: deque() for name in self.parts}
        self._exited = threading.Event()

    def _print_line(self, name: str, line: str) -> None:
        if self.echo:
            print(f"  [{name}] {line}", flush=True)

    def start(self) -> None:
        """Start every part in order and wait until each serves.

        Raises:
            StackFailed: a part exited or did not become ready; everything started is stopped.
        """
        try:
            for name in self.parts:
                self._start_part(name)
        except ProcessFailed as exc:
            self.stop()
            raise StackFailed(str(exc)) from None

    def _start_part(self, name: str) -> None:
        started = time.monotonic()
        proc = caretaker(*self.parts[name], env=self.env, name=name, on_line=self._print_line)
        self.processes[name] = proc
        threading.Thread(target=self._await_exit, args=(proc,), name=f"{name}-exit", daemon=True).start()
        self.ready_lines[name] = proc.wait_ready(self.ready_timeout)
        log.info("%s ready in %.1f s: %s", name, time.monotonic() - started, self.ready_lines[name])

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
                print(f"{name} died (exit {code}); restarting it", flush=True)
                try:
                    self._start_part(name)
                except ProcessFailed as exc:
                    print(f"{name} did not come back: {exc}", file=sys.stderr, flush=True)
                    return self.dead_parts()
                print(f"restarted {name}: {self.ready_lines[name]}", flush=True)
        return []

    def wake(self) -> None:
        """End a :meth:`supervise` wait (from a signal handler)."""
        self._exited.set()

    def _may_restart(self, name: str) -> bool:
        if not self.respawn or name == WORLD:
            return False
        now = time.monotonic()
        recent = self.restarts[name]
        while recent and now - recent[0] > RESPAWN_WINDOW_S:
            recent.popleft()
        if len(recent) >= RESPAWN_LIMIT:
            print(f"{name} died {RESPAWN_LIMIT + 1} times within {RESPAWN_WINDOW_S:.0f} s: not restarting it again", file=sys.stderr)
            return False
        recent.append(now)
        return True

    def stop(self) -> None:
        """Stop every part, last started first, and remove the stack's folder. Idempotent."""
        for name in reversed(list(self.parts)):
            proc = self.processes.get(name)
            if proc is not None:
                log.info("%s stopped (exit %s)", name, proc.stop())
        if self.state_dir is not None:
            shutil.rmtree(self.state_dir, ignore_errors=True)


def _parser(prog: str) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog=prog)
    parser.add_argument("--time-scale", type=float, default=1.0, help="simulation speed: 1 = real time, 0 = as fast as possible")
    parser.add_argument("--bridge-address", default="127.0.0.1")
    parser.add_argument("--bridge-port", type=int, default=9090)
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
    """``caretaker up --scene iva|eva``: run the robot side and the bridge until Ctrl-C."""
    parser = _parser("caretaker up")
    parser.add_argument("--scene", choices=sorted(SCENARIOS), required=True)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    stack = Stack(
        SCENARIOS[args.scene],
        time_scale=args.time_scale,
        bridge_address=args.bridge_address,
        bridge_port=args.bridge_port,
        echo=args.verbose,
        respawn=True,
    )
    try:
        stack.start()
    except StackFailed as exc:
        print(f"caretaker up: {exc}", file=sys.stderr)
        return 1
    for name, line in stack.ready_lines.items():
        print(f"{name:10} {line}")
    print("READY stack", args.scene, flush=True)
    return _run_until_signal(stack)


def demo_main(argv: list[str] | None = None) -> int:
    """``caretaker demo iva|eva``: bring the stack up, run the procedure autonomously, report."""
    from caretaker.demo import run_demo

    parser = _parser("caretaker demo")
    parser.add_argument("scenario", choices=sorted(SCENARIOS))
    parser.add_argument("--serve", action="store_true", help="leave the web view running after the procedure")
    parser.add_argument("--db", default=None, help="audit log SQLAlchemy URL (default: var/caretaker.db)")
    parser.set_defaults(time_scale=0.0)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    return run_demo(SCENARIOS[args.scenario], args)
