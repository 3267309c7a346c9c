"""Ground and habitat as two hosts in the tests: network namespaces joined only by the link.

Three namespaces per fixture::

    ground (10.77.1.2) ── veth ── link (10.77.1.1 | 10.77.2.1) ── veth ── habitat (10.77.2.2)

The link namespace forwards nothing (IP forwarding stays off, as in every new namespace), so
the only way from ground to habitat is a TCP relay running there: ``caretaker link``, listening
on its ground-side address and connecting to a habitat address. DDS stays inside the habitat:
each namespace has its own loopback, and the session's ROS settings keep discovery on it.

Names start with ``ct2h-<pid>-<n>`` (namespaces) and ``ct<pid>x<n>`` (interfaces), so parallel
sessions never collide; :func:`remove_stale_namespaces` removes those of sessions whose process
is gone (never a live session's). Needs root (CI and the dev machines run as root).
"""

from __future__ import annotations

import contextlib
import itertools
import logging
import os
import re
import shutil
import signal
import subprocess
import tempfile
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from caretaker.link import LinkControl
from caretaker.processes import VENV_BIN, ManagedProcess

__all__ = ["Host", "LinkProcess", "TwoHosts", "remove_stale_namespaces"]

log = logging.getLogger("tests.two_hosts")

_STALE = re.compile(r"^ct2h-(\d+)-(\d+)-(ground|link|habitat)$")
_counter = itertools.count(1)


@dataclass(frozen=True)
class Host:
    """One namespace: ``address`` is where the other side reaches it (the link: its ground side)."""

    role: str
    namespace: str
    address: str


@dataclass
class LinkProcess:
    """``caretaker link`` running in the link namespace; clients on the ground connect to ``address``."""

    process: ManagedProcess
    control: LinkControl
    address: tuple[str, int]

    @property
    def url(self) -> str:
        """The rosbridge URL the ground side uses to reach the habitat through the link."""
        return f"ws://{self.address[0]}:{self.address[1]}"


def _ip(*args: str, check: bool = True) -> subprocess.CompletedProcess[str]:
    return subprocess.run(["ip", *args], capture_output=True, text=True, timeout=30, check=check)


def _namespaces() -> list[str]:
    return [line.split()[0] for line in _ip("netns", "list").stdout.splitlines() if line.strip()]


def _delete_namespace(namespace: str) -> None:
    """Kill whatever still runs in ``namespace``, then delete it (its veths go with it)."""
    pids = _ip("netns", "pids", namespace, check=False).stdout.split()
    for pid in pids:
        with contextlib.suppress(ProcessLookupError):
            os.kill(int(pid), signal.SIGKILL)
    result = _ip("netns", "delete", namespace, check=False)
    if result.returncode != 0 and namespace in _namespaces():
        raise RuntimeError(f"cannot delete network namespace {namespace}: {result.stderr.strip()}")


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def remove_stale_namespaces() -> list[str]:
    """Delete the namespaces this fixture made in sessions whose process has died; return them."""
    stale = [name for name in _namespaces() if (match := _STALE.match(name)) and not _alive(int(match[1]))]
    for namespace in stale:
        log.warning("removing stale network namespace %s (its test session is gone)", namespace)
        _delete_namespace(namespace)
    for folder in Path(tempfile.gettempdir()).glob("ct2h-*"):
        if (match := re.match(r"^ct2h-(\d+)-", folder.name)) and not _alive(int(match[1])):
            shutil.rmtree(folder, ignore_errors=True)
    return stale


@dataclass
class TwoHosts:
    """The ground, link and habitat namespaces of one test, and every process started in them.

    Create with :meth:`create` (a context manager): leaving it stops the processes and deletes
    the namespaces, also when the test failed.
    """

    ground: Host
    link: Host
    habitat: Host
    env: dict[str, str]
    folder: Path
    link_habitat_side: str = "10.77.2.1"
    processes: list[ManagedProcess] = field(default_factory=list)

    @classmethod
    @contextlib.contextmanager
    def create(cls, env: dict[str, str]) -> Iterator[TwoHosts]:
        """Make the three namespaces and their veths; yield them; tear everything down.

        ``env`` is the session's environment (ROS_DOMAIN_ID, ...); discovery is kept on each
        namespace's loopback whatever it says.
        """
        remove_stale_namespaces()
        serial = next(_counter)
        prefix = f"ct2h-{os.getpid()}-{serial}"
        folder = Path(tempfile.mkdtemp(prefix=f"{prefix}-"))
        hosts = cls(
            Host("ground", f"{prefix}-ground", "10.77.1.2"),
            Host("link", f"{prefix}-link", "10.77.1.1"),
            Host("habitat", f"{prefix}-habitat", "10.77.2.2"),
            # TMPDIR: what the processes leave behind (a console's runners' logs) goes when the folder goes
            {**env, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST", "TMPDIR": str(folder)},
            folder,
        )
        created: list[str] = []
        try:
            for host in (hosts.ground, hosts.link, hosts.habitat):
                _ip("netns", "add", host.namespace)
                created.append(host.namespace)
                _ip("-n", host.namespace, "link", "set", "lo", "up")
            interface = f"ct{os.getpid()}x{serial}"
            hosts._join(hosts.ground, hosts.ground.address, f"{interface}g", hosts.link.address, f"{interface}a")
            hosts._join(hosts.habitat, hosts.habitat.address, f"{interface}h", hosts.link_habitat_side, f"{interface}b")
            forwarding = hosts.run(hosts.link, ["cat", "/proc/sys/net/ipv4/ip_forward"]).stdout.strip()
            if forwarding != "0":
                raise RuntimeError(f"IP forwarding is on in {hosts.link.namespace}: ground could bypass the link")
            yield hosts
        finally:
            hosts._stop_processes()
            for namespace in reversed(created):
                _delete_namespace(namespace)
            shutil.rmtree(hosts.folder, ignore_errors=True)

    def _join(self, host: Host, address: str, name: str, link_address: str, link_name: str) -> None:
        """A veth pair from ``host`` to the link namespace, both ends made inside their namespaces."""
        _ip(
            "link",
            "add",
            name,
            "netns",
            host.namespace,
            "type",
            "veth",
            "peer",
            "name",
            link_name,
            "netns",
            self.link.namespace,
        )
        for namespace, device, ip in ((host.namespace, name, address), (self.link.namespace, link_name, link_address)):
            _ip("-n", namespace, "addr", "add", f"{ip}/24", "dev", device)
            _ip("-n", namespace, "link", "set", device, "up")

    def _stop_processes(self) -> None:
        for process in reversed(self.processes):
            process.stop()
        self.processes.clear()

    # ---- running things in a namespace --------------------------------------------------------

    def _in(self, host: Host, argv: Sequence[str]) -> list[str]:
        return ["ip", "netns", "exec", host.namespace, *argv]

    def run(
        self, host: Host, argv: Sequence[str], *, timeout: float = 60.0, check: bool = True
    ) -> subprocess.CompletedProcess[str]:
        """Run a short command in ``host`` and return its result (raises on failure if ``check``)."""
        return subprocess.run(
            self._in(host, argv), env=self.env, capture_output=True, text=True, timeout=timeout, check=check
        )

    def start(
        self,
        host: Host,
        argv: Sequence[str],
        *,
        name: str | None = None,
        ready: str | None = r"^READY\b",
        timeout: float = 90.0,
    ) -> ManagedProcess:
        """Start a long-running process in ``host``; wait for a line matching ``ready`` (None: don't).

        The process is stopped when the fixture ends (or earlier by ``process.stop()``).
        """
        process = ManagedProcess(self._in(host, argv), self.env, f"{host.role}:{name or Path(argv[0]).name}")
        self.processes.append(process)
        if ready is not None:
            process.wait_for_line(ready, timeout)
        return process

    def caretaker(
        self, host: Host, *args: str, ready: str | None = r"^READY\b", timeout: float = 90.0
    ) -> ManagedProcess:
        """Start ``caretaker ARGS...`` in ``host``."""
        return self.start(
            host,
            [str(VENV_BIN / "caretaker"), *args],
            name=args[0] if args else "caretaker",
            ready=ready,
            timeout=timeout,
        )

    def python(self, host: Host, *args: str, ready: str | None = r"^READY\b", timeout: float = 90.0) -> ManagedProcess:
        """Start the venv's ``python ARGS...`` in ``host``."""
        return self.start(
            host,
            [str(VENV_BIN / "python"), *args],
            name=Path(args[0]).stem if args else "python",
            ready=ready,
            timeout=timeout,
        )

    def start_link(
        self, *, target_port: int, port: int = 9090, delay: float = 0.2, options: Sequence[str] = ()
    ) -> LinkProcess:
        """Start ``caretaker link`` from the link's ground side ``port`` to the habitat's ``target_port``.

        ``options`` are more ``caretaker link`` options (``--loss 0.05``, ``--outage hold:30@40``...).
        """
        control = self.folder / f"link-{port}.sock"
        process = self.caretaker(
            self.link,
            "link",
            "--listen",
            f"{self.link.address}:{port}",
            "--to",
            f"{self.habitat.address}:{target_port}",
            "--delay",
            str(delay),
            "--control",
            str(control),
            *options,
        )
        return LinkProcess(process, LinkControl(control), (self.link.address, port))
