"""Starting ``caretaker serve`` for the browser tests, as a real process with simulated systems behind it."""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from pride.web.accounts import AccountStore
from support.processes import ManagedProcess, caretaker
from support.stack import stack_up

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]

#: The people of the browser tests: user id -> (role, name, password).
PEOPLE = {
    "alice": ("operator", "Alice (ground operator)", "alice-correct-horse"),
    "bob": ("operator", "Bob (flight controller)", "bob-battery-staple"),
    "carol": ("observer", "Carol (observer)", "carol-watches-only"),
}


class WebServer:
    """A running ``caretaker serve`` and where it listens."""

    def __init__(self, process: ManagedProcess, url: str, db: Path, procedures: Path) -> None:
        self.process = process
        self.url = url
        self.db = db
        self.procedures = procedures


def start_server(
    tmp: Path, procedures: Path, *, db: Path | None = None, rosbridge: str | None = None, sysreps: Path | None = None
) -> WebServer:
    """Start a server listing ``procedures``, writing the audit log ``db`` (a new one in ``tmp``, with
    the test people's accounts, by default) and reading SysReps from ``sysreps`` (the shipped ones by default).

    With ``rosbridge`` the server opens the real PAX host (JVM plugins) on that rosbridge;
    without, the simulated systems of simulated_systems.py.
    """
    env = dict(os.environ)
    options = ["--camera", "ee_camera", "--camera-period", "0.1", *(["--sysreps", str(sysreps)] if sysreps else [])]
    if rosbridge is None:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(HERE), env.get("PYTHONPATH", "")]))
        env["PRIDE_GATEWAY"] = "simulated_systems:open_simulated_systems"
        env["SIMULATED_MOTION_S"] = "0.6"
    else:
        env.pop("PRIDE_GATEWAY", None)
        options += ["--rosbridge", rosbridge]
    if db is None:
        db = tmp / "audit.db"
        add_people(f"sqlite:///{db}")
    process = caretaker(
        "serve", "--port", "0", "--db", f"sqlite:///{db}", "--procedures", str(procedures),
        "--reports", str(tmp / "reports"), *options, env=env, name="serve",
    )
    try:
        ready = process.wait_ready(90)
    except Exception:
        process.stop()
        raise
    return WebServer(process, ready.split()[-1], db, procedures)


def add_people(db_url: str) -> None:
    """The test people's accounts in a new ground database (what `caretaker accounts add` writes)."""
    store = AccountStore(db_url)
    try:
        for user, (role, name, password) in PEOPLE.items():
            store.add(user, role, password, name=name)
    finally:
        store.close()


@contextmanager
def server_on_real_stack(tmp: Path, procedures: Path, env: dict[str, str]) -> Iterator[WebServer]:
    """``caretaker up iva`` (simulation, planner, AT server, rosbridge) and a server on it."""
    with stack_up("iva", env) as stack:
        served = start_server(tmp, procedures, rosbridge=stack.url)
        try:
            yield served
        finally:
            served.process.stop()


def procedure_shelf(tmp: Path) -> Path:
    """The shipped procedures plus this suite's walk-through, in one directory the server lists."""
    shelf = tmp / "procedures"
    shelf.mkdir()
    for source in [*sorted((REPO / "procedures").glob("*.xml")), *sorted((HERE / "fixtures" / "procedures").glob("*.xml"))]:
        (shelf / source.name).symlink_to(source)
    return shelf
