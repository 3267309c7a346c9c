"""Emulated habitats for the ground: the real onboard services on a robot that costs nothing.

One ground serves many habitats (``caretaker supervise`` keeps a session to each); testing or
measuring that with a real robot side per habitat (simulation, planner, JVM) costs a machine per
habitat. An emulated habitat is the habitat's own processes minus the robot: a real
``caretaker bridge`` (wss:// on loopback, the link's secret, as a flight's habitat serves it,
flight_support.py) and a real ``caretaker onboard`` whose gateway is the in-process simulated IVA
robot (``PRIDE_GATEWAY``, support/simulated_systems.py), answering each command as long after as
the real robot side took in the recorded IVA run (tests/pride/fixtures/iva_recorded_run.json,
``SIMULATED_PACE``); the ground reaches it through ``caretaker link --delay``. The onboard executive
runs the real IVA procedure, so a run's chain is a real chain with real hashes. For tests and
benches of the ground only: never a way to show a robot that is not there.

Each habitat has its own ground binding, ``<name>.yaml`` naming robot ``<name>`` (a supervisor
serves several, a handoff names its binding by file name), its own link credentials and its own
ROS domain (the bridges' services are ROS services: two habitats on one domain would answer each
other's calls).
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import re
import time
import zlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from caretaker.certs import make_link_credentials
from caretaker.processes import REPO, ManagedProcess, caretaker
from flight.flight_support import CLEAN_FILTER, PROCEDURE, onboard_chain, write_ground_binding
from records.audit_chain import StoredEvent
from records.onboard_handoffs import OnboardHandoffs
from support.recorded_run import IVA_RUN
from support.ros_domain import claim_ros_domain
from support.second_operator import APPROVED_BY_BOB
from support.stack import write_deployment

__all__ = ["EmulatedHabitat", "Takeover", "emulated_habitat", "fleet", "kill_the_busier", "supervise"]

HOST = "127.0.0.1"
#: How long a part may take to say READY (a bridge loads rclpy; ten habitats start on two cores).
READY_S = 180.0


@dataclass
class EmulatedHabitat:
    """One emulated habitat: its processes, the ground binding that reaches it and its onboard store."""

    name: str
    binding: Path
    state_dir: Path
    bridge: ManagedProcess
    link: ManagedProcess
    onboard: ManagedProcess

    def onboard_chain(self, run_id: str) -> list[StoredEvent]:
        """The run's events as the habitat's onboard store holds them."""
        return onboard_chain(self.state_dir, run_id)

    def hand_run(self, db: str, env: dict[str, str]) -> ManagedProcess:
        """``caretaker run`` of the IVA procedure for this habitat, autonomous, handed to the
        supervisors of ``db`` (``--onboard --via-supervisor``) and followed to its end; bob approves
        the unlock (``env`` has his password: support/second_operator.py)."""
        return caretaker(
            *("run", str(PROCEDURE), "--binding", str(self.binding), "--auto", "--user", "flight", "--db", db),
            *("--confirm-manual", *APPROVED_BY_BOB, "--rehearsal", f"--set=clean_filter_id={CLEAN_FILTER}"),
            *("--onboard", "--via-supervisor"),
            env=env,
            name=f"run-{self.name}",
        )


def _address(line: str) -> int:
    """The port of a ``READY bridge wss://HOST:PORT`` or ``READY link HOST:PORT -> ...`` line."""
    found = re.search(r"\b127\.0\.0\.1:(\d+)", line)
    if found is None:
        raise ValueError(f"no {HOST}:PORT in {line!r}")
    return int(found[1])


@contextlib.contextmanager
def emulated_habitat(
    name: str, folder: Path, env: dict[str, str], *, delay: float, loss: float = 0.0, pace: Path | None = IVA_RUN
) -> Iterator[EmulatedHabitat]:
    """The habitat ``name`` serving in ``folder / name`` (which the caller removes), ``delay`` s one
    way from the ground, losing the share ``loss`` of the link's segments each way (``caretaker
    link --loss``); ``pace``: a recorded run whose robot pace it keeps (None: flat out).
    Every process is stopped when the block is left, also when it fails."""
    home = folder / name
    home.mkdir(parents=True)
    env = {
        **env,
        "ROS_DOMAIN_ID": str(claim_ros_domain()),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
        "TMPDIR": str(home),  # what its parts leave, even killed, goes with the folder
    }
    credentials = make_link_credentials(home / "link", [HOST], days=2)
    started: list[ManagedProcess] = []

    def start(*args: str, part: str) -> tuple[ManagedProcess, str]:
        process = caretaker(*args, env=gateway_env if part == "onboard" else env, name=f"{name}:{part}")
        started.append(process)
        return process, process.wait_for_line(r"^READY ", READY_S)

    gateway_env = {
        **env,
        "PYTHONPATH": str(REPO / "tests"),  # support.simulated_systems, which PRIDE_GATEWAY names
        "PRIDE_GATEWAY": "support.simulated_systems:open_simulated_systems",
        "SIMULATED_CAMERA_DIR": str(home),
        **({"SIMULATED_PACE": str(pace)} if pace else {}),
    }
    try:
        bridge, ready = start(
            "bridge",
            *("--address", HOST, "--port", "0", "--certfile", str(credentials["bridge.pem"])),
            *("--keyfile", str(credentials["bridge.key"]), "--auth-secret-file", str(credentials["rosbridge.secret"])),
            part="bridge",
        )
        bridge_port = _address(ready)
        link, ready = start(
            *("link", "--listen", f"{HOST}:0", "--to", f"{HOST}:{bridge_port}"),
            *("--delay", f"{delay:g}", "--loss", f"{loss:g}"),
            *("--seed", str(zlib.crc32(name.encode()))),  # each habitat's losses its own, not the fleet's in step
            part="link",
        )
        url = f"wss://{HOST}:{_address(ready)}"
        binding = write_ground_binding(home, url, credentials, one_way_delay=delay, outage_budget=120.0, robot=name)
        state_dir = home / "onboard"
        # beside the binding, where the ground looks: a simulator (rehearsals run), hazardous commands approved
        write_deployment(home, "iva-habitat", name=f"{name}-habitat", bindings=[str(binding)], onboard=True)
        onboard, _ = start(
            "onboard",
            *("--bridge", f"wss://{HOST}:{bridge_port}", "--binding", str(binding), "--state-dir", str(state_dir)),
            part="onboard",
        )
        yield EmulatedHabitat(name, binding, state_dir, bridge, link, onboard)
    finally:
        for process in reversed(started):
            process.stop()


#: Habitats started at once: each start waits on its processes' READY lines one after another.
_STARTING_AT_ONCE = 4


@contextlib.contextmanager
def fleet(
    folder: Path, env: dict[str, str], delays: Sequence[float], *, loss: float = 0.0, pace: Path | None = IVA_RUN
) -> Iterator[list[EmulatedHabitat]]:
    """One emulated habitat per one-way delay in ``delays``, named ``iva-hab01``, ``iva-hab02``...,
    each link losing the share ``loss`` of its segments; started a few at once, and every one
    that started stopped when the block is left (also when another failed to start)."""
    starts = [
        emulated_habitat(f"iva-hab{n:02d}", folder, env, delay=delay, loss=loss, pace=pace)
        for n, delay in enumerate(delays, 1)
    ]
    with contextlib.ExitStack() as stack:
        # left last: a process dies with the thread that started it (PR_SET_PDEATHSIG, caretaker.processes)
        pool = stack.enter_context(concurrent.futures.ThreadPoolExecutor(_STARTING_AT_ONCE, "habitat-start"))
        entering = [pool.submit(start.__enter__) for start in starts]
        concurrent.futures.wait(entering)
        for start, entered in zip(starts, entering, strict=True):
            if entered.exception() is None:
                stack.push(start.__exit__)
        failed = [error for entered in entering if (error := entered.exception()) is not None]
        if failed:
            raise failed[0]
        yield [entered.result() for entered in entering]


def supervise(
    db: str, habitats: Sequence[EmulatedHabitat], env: dict[str, str], name: str
) -> tuple[ManagedProcess, str]:
    """``caretaker supervise`` of every habitat's binding on ``db``, once it serves each; (process,
    the name it supervises as, which handoffs and takeovers name)."""
    bindings = [option for h in habitats for option in ("--binding", str(h.binding))]
    process = caretaker("supervise", "--db", db, *bindings, env=env, name=name)
    ready = ""
    for h in habitats:
        ready = process.wait_for_line(rf"^READY supervise {re.escape(h.binding.name)} ", READY_S)
    return process, ready.split(" as ", 1)[1]


@dataclass(frozen=True)
class Takeover:
    """A supervisor killed and the other taking its runs over: who, which runs, and how long it took (s)."""

    victim: str
    survivor: str
    held: dict[str, list[str]]  # supervisor -> the runs it held when the kill came
    seconds: float


def kill_the_busier(
    supervisors: Sequence[tuple[ManagedProcess, str]],
    run_ids: Sequence[str],
    handoffs: OnboardHandoffs,
    mid_run: Callable[[list[str]], None],
    *,
    within: float,
) -> Takeover:
    """SIGKILL whichever of two supervisors holds more of ``run_ids``, once ``mid_run(its runs)``
    returns (it waits until they are under way), and wait up to ``within`` s for the other's
    ``TAKEN OVER`` of each of them.

    Raises:
        ValueError: a run was not taken by one of ``supervisors``.
        ProcessFailed: the survivor did not take a run over in time.
    """
    named = {name: process for process, name in supervisors}
    held: dict[str, list[str]] = {name: [] for name in named}
    for run_id in run_ids:
        handoff = handoffs.get(run_id)
        if handoff is None or handoff.supervisor not in held:
            raise ValueError(f"{run_id}: not taken by one of {sorted(named)}: {handoff}")
        held[handoff.supervisor].append(run_id)
    victim = max(held, key=lambda name: len(held[name]))
    survivor = next(name for name in named if name != victim)
    mid_run(held[victim])
    killed = time.monotonic()
    named[victim].kill()
    for run_id in held[victim]:
        named[survivor].wait_for_line(rf"^{run_id}: TAKEN OVER from {re.escape(victim)} ", within)
    return Takeover(victim, survivor, held, time.monotonic() - killed)
