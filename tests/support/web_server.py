"""Starting ``caretaker serve`` for the browser tests, as a real process with simulated systems behind it."""

from __future__ import annotations

import itertools
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from console.accounts import AccountStore
from support.postgres import OWNER, RUNNER, PostgresServer
from support.processes import ManagedProcess, caretaker
from support.stack import stack_up

REPO = Path(__file__).resolve().parents[2]
TESTS = REPO / "tests"  # on the server's path: its simulated systems are support.simulated_systems
WEB = TESTS / "web"  # the web suite's procedure fixtures

#: The people of the browser tests: user id -> (role, name, password).
PEOPLE = {
    "alice": ("operator", "Alice (ground operator)", "alice-correct-horse"),
    "bob": ("operator", "Bob (flight controller)", "bob-battery-staple"),
    "carol": ("observer", "Carol (observer)", "carol-watches-only"),
}


@dataclass(frozen=True)
class GroundDatabase:
    """A ground database with the test people's accounts: ``url`` is what consoles use (on
    PostgreSQL the locked-down runner role), ``owner_url`` what `caretaker accounts` uses."""

    kind: str
    url: str
    owner_url: str


_databases = itertools.count(1)


def new_ground_database(kind: str, tmp: Path, postgres: PostgresServer | None = None) -> GroundDatabase:
    """A new SQLite file in ``tmp``, or a new database on ``postgres``, migrated by its owner, with PEOPLE."""
    if kind == "sqlite":
        url = f"sqlite:///{tmp / f'ground-{next(_databases)}.db'}"
        database = GroundDatabase(kind, url, url)
    else:
        assert postgres is not None, "a PostgreSQL ground database needs the session's server"
        name = postgres.new_database()
        database = GroundDatabase(kind, postgres.url(name, RUNNER), postgres.url(name, OWNER))
    add_people(database.owner_url)
    return database


class WebServer:
    """A running ``caretaker serve`` and where it listens."""

    def __init__(self, process: ManagedProcess, url: str, database: GroundDatabase, procedures: Path) -> None:
        self.process = process
        self.url = url
        self.database = database
        self.procedures = procedures
        self.rosbridge: str | None = None  # on a real stack: its rosbridge URL, which the server uses


def start_server(
    tmp: Path,
    procedures: Path,
    *,
    database: GroundDatabase | None = None,
    rosbridge: Sequence[str] | None = None,
    sysreps: Path | None = None,
    cameras: Sequence[str] = ("ee_camera",),
    options: Sequence[str] = (),
    env: dict[str, str] | None = None,
) -> WebServer:
    """Start a server listing ``procedures`` on ``database`` (a new SQLite one in ``tmp`` by default)
    and reading SysReps from ``sysreps`` (the shipped ones by default); ``cameras``: ``--camera`` values.

    With ``rosbridge`` (``--rosbridge`` values: a URL, or BINDING=URL per robot) the server opens
    the real PAX host (JVM plugins); without, the simulated systems of simulated_systems.py.
    """
    env = dict(env if env is not None else os.environ)
    env["TMPDIR"] = str(tmp)  # the runners' logs it starts (kept after it ends) go with the test's files
    arguments = [
        *(f"--camera={camera}" for camera in cameras),
        "--camera-period",
        "0.1",
        *(["--sysreps", str(sysreps)] if sysreps else []),
        *options,
    ]
    if rosbridge is None:
        env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(TESTS), env.get("PYTHONPATH", "")]))
        env["PRIDE_GATEWAY"] = "support.simulated_systems:open_simulated_systems"
        env["SIMULATED_MOTION_S"] = "0.6"
        env["SIMULATED_CAMERA_DIR"] = str(tmp)
    else:
        env.pop("PRIDE_GATEWAY", None)
        arguments += [f"--rosbridge={url}" for url in rosbridge]
    if database is None:
        database = new_ground_database("sqlite", tmp)
    process = caretaker(
        "serve",
        "--port",
        "0",
        "--db",
        database.url,
        "--procedures",
        str(procedures),
        "--reports",
        str(tmp / "reports"),
        *arguments,
        env=env,
        name="serve",
    )
    try:
        ready = process.wait_ready(90)
    except Exception:
        process.stop()
        raise
    return WebServer(process, ready.split()[-1], database, procedures)


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
        served = start_server(tmp, procedures, rosbridge=[stack.url])
        served.rosbridge = stack.url
        try:
            yield served
        finally:
            served.process.stop()


def procedure_shelf(tmp: Path) -> Path:
    """The shipped procedures plus this suite's walk-through, in one directory the server lists."""
    shelf = tmp / "procedures"
    shelf.mkdir()
    shipped, fixtures = REPO / "procedures", WEB / "fixtures" / "procedures"
    for source in [*sorted(shipped.glob("*.xml")), *sorted(fixtures.glob("*.xml"))]:
        (shelf / source.name).symlink_to(source)
    return shelf
