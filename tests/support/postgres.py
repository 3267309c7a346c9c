"""A PostgreSQL server of the test session's own: Debian's binaries, a temporary cluster, loopback only.

Tests and benchmarks run against a real server, never the package's system cluster: ``initdb``
makes a cluster in a temporary directory, ``pg_ctl`` starts it on a free port listening on
127.0.0.1 with its unix socket inside that directory, and :meth:`PostgresServer.remove` stops it
and deletes everything. PostgreSQL refuses to run as root, so when we are root the cluster
belongs to the ``postgres`` system user (the Debian package creates it) and every server
command runs as that user through ``runuser``.

The cluster has the roles of a ground segment (docs/ground-segment.md): the bootstrap superuser
``postgres``, ``caretaker_owner`` who owns the audit-log databases and runs their migrations,
the group role ``caretaker_runner`` and ``pax``, a login role in it that runners connect as.
Connections from loopback are trusted (no passwords in tests); the grants are what is tested.

:meth:`stop`, :meth:`start` and :meth:`restart` keep the cluster and port, so a test can take the
database away in the middle of a run and bring it back.
"""

from __future__ import annotations

import contextlib
import itertools
import os
import pwd
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from support.ports import free_port

__all__ = ["OWNER", "RUNNER", "RUNNER_GROUP", "SUPERUSER", "PostgresServer", "PostgresUnavailable", "postgres_server"]

SUPERUSER = "postgres"
OWNER = "caretaker_owner"
RUNNER_GROUP = "caretaker_runner"
RUNNER = "pax"
_SYSTEM_USER = "postgres"
_TIMEOUT = 60


class PostgresUnavailable(RuntimeError):
    """PostgreSQL's server binaries are missing or the cluster could not be made; says what to do."""


def _bin_dir() -> Path:
    versions = sorted(Path("/usr/lib/postgresql").glob("*/bin/pg_ctl"), key=lambda p: int(p.parts[-3]))
    if not versions:
        raise PostgresUnavailable(
            "no /usr/lib/postgresql/<version>/bin/pg_ctl: run `make setup` (it installs Debian's postgresql)"
        )
    return versions[-1].parent


@dataclass
class PostgresServer:
    """One temporary cluster; create it with :func:`postgres_server` or :meth:`create`."""

    directory: Path
    port: int
    bin_dir: Path = field(default_factory=_bin_dir)
    _names: Iterator[int] = field(default_factory=lambda: itertools.count(1))

    @property
    def data_dir(self) -> Path:
        return self.directory / "data"

    @property
    def socket_dir(self) -> Path:
        return self.directory / "socket"

    @classmethod
    def create(cls, *, settings: dict[str, str] | None = None) -> PostgresServer:
        """initdb a cluster in a new temporary directory, start it, and create the ground-segment roles."""
        directory = Path(tempfile.mkdtemp(prefix="ct-postgres-"))
        server = cls(directory, free_port())
        try:
            server.socket_dir.mkdir()
            if os.geteuid() == 0:
                user = pwd.getpwnam(_SYSTEM_USER)
                for path in (directory, server.socket_dir):
                    os.chown(path, user.pw_uid, user.pw_gid)
            server._server_command(
                "initdb",
                "--auth=trust",
                f"--username={SUPERUSER}",
                "--encoding=UTF8",
                "--locale=C.UTF-8",
                "--no-instructions",
                "--no-sync",  # a scratch cluster: its files need not reach the disk before it starts
                "-D",
                str(server.data_dir),
            )
            conf = [
                f"port = {server.port}",
                "listen_addresses = '127.0.0.1'",
                f"unix_socket_directories = '{server.socket_dir}'",
                "max_connections = 200",
            ]
            conf += [f"{name} = {value}" for name, value in (settings or {}).items()]
            with (server.data_dir / "postgresql.auto.conf").open("a", encoding="utf-8") as auto:
                auto.write("\n".join(conf) + "\n")
            server.start()
            server.sql(
                f"CREATE ROLE {OWNER} LOGIN",
                f"CREATE ROLE {RUNNER_GROUP} NOLOGIN",
                f"CREATE ROLE {RUNNER} LOGIN IN ROLE {RUNNER_GROUP}",
            )
        except BaseException:
            server.remove()
            raise
        return server

    def _server_command(self, program: str, *args: str) -> str:
        command = [str(self.bin_dir / program), *args]
        if os.geteuid() == 0:
            command = ["runuser", "-u", _SYSTEM_USER, "--", *command]
        done = subprocess.run(
            command, capture_output=True, text=True, timeout=_TIMEOUT, cwd=self.directory, stdin=subprocess.DEVNULL
        )
        if done.returncode != 0:
            log = self.directory / "server.log"
            tail = log.read_text(errors="replace")[-2000:] if log.exists() else ""
            raise PostgresUnavailable(
                f"{program} {' '.join(args)} failed ({done.returncode}): {done.stderr.strip()}\n{tail}"
            )
        return done.stdout

    def start(self) -> None:
        """Start the server and return once it accepts connections."""
        self._server_command(
            "pg_ctl",
            "start",
            "-w",
            "-t",
            str(_TIMEOUT),
            "-D",
            str(self.data_dir),
            "-l",
            str(self.directory / "server.log"),
        )

    def stop(self) -> None:
        """Stop the server (fast shutdown: open connections are cut, committed data is kept)."""
        self._server_command("pg_ctl", "stop", "-w", "-t", str(_TIMEOUT), "-m", "fast", "-D", str(self.data_dir))

    def restart(self) -> None:
        self.stop()
        self.start()

    def running(self) -> bool:
        return (self.data_dir / "postmaster.pid").exists()

    def url(self, database: str = "postgres", role: str = SUPERUSER) -> str:
        """SQLAlchemy URL of ``database`` as ``role`` over TCP on loopback."""
        return f"postgresql+psycopg://{role}@127.0.0.1:{self.port}/{database}"

    def sql(self, *statements: str, database: str = "postgres", role: str = SUPERUSER) -> list[tuple[object, ...]]:
        """Run statements in autocommit (CREATE DATABASE needs it); rows of the last one that returned any."""
        import psycopg

        rows: list[tuple[object, ...]] = []
        with psycopg.connect(host="127.0.0.1", port=self.port, user=role, dbname=database, autocommit=True) as conn:
            for statement in statements:
                cursor = conn.execute(statement)  # type: ignore[arg-type]  # test-written SQL, not user input
                if cursor.description is not None:
                    rows = cursor.fetchall()
        return rows

    def new_database(self, *, template: str | None = None) -> str:
        """Create an empty database owned by ``caretaker_owner`` (or a copy of ``template``); its name."""
        name = f"ct_{next(self._names)}"
        self.sql(f"CREATE DATABASE {name} OWNER {OWNER}" + (f" TEMPLATE {template}" if template else ""))
        return name

    def remove(self) -> None:
        """Stop the server if it runs and delete the cluster."""
        with contextlib.suppress(PostgresUnavailable):
            if self.running():
                self.stop()
        shutil.rmtree(self.directory, ignore_errors=True)


@contextlib.contextmanager
def postgres_server(*, settings: dict[str, str] | None = None) -> Iterator[PostgresServer]:
    """A running temporary cluster for the duration of the ``with`` block."""
    server = PostgresServer.create(settings=settings)
    try:
        yield server
    finally:
        server.remove()
