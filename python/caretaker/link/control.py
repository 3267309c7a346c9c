"""The link's control socket: start outages and read byte counts while the link runs.

A Unix socket speaking one JSON object per line each way, so a test, a bench or an operator
with ``socat`` can drive it:

- ``{"outage": "hold", "seconds": 30}`` → ``{"ok": true, "outage": "hold", "seconds": 30}``
- ``{"outage": "reset", "seconds": 10}`` → likewise
- ``{"stats": true}`` → ``{"ok": true, "stats": {...}}`` (stats.py: totals and per connection)

Anything else is answered ``{"ok": false, "error": "..."}`` and the link goes on. A Unix socket
rather than TCP: it is reachable from every network namespace of the host (the file system is
shared), and only by who may open the file.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import math
import os
import socket
import stat
from pathlib import Path
from typing import Any

from .model import Outage, OutageKind
from .relay import LinkEmulator
from .stats import LinkStats

__all__ = ["ControlServer", "ControlSocketError", "JsonLineClient", "LinkControl", "LinkControlError"]

log = logging.getLogger("caretaker.link.control")

#: Longest request line; a longer one is refused (the socket is reachable by any local user with access).
MAX_REQUEST = 4096
#: sun_path holds 108 bytes including the terminating NUL.
MAX_SOCKET_PATH = 107


class ControlSocketError(OSError):
    """The control socket cannot be created at ``path`` (too long, in use, not a socket)."""

    def __init__(self, path: Path, problem: str) -> None:
        super().__init__(f"control socket {path}: {problem}")
        self.path = path


class LinkControlError(RuntimeError):
    """A control request was refused; ``request`` is what was sent, ``error`` the answer's reason."""

    def __init__(self, request: dict[str, Any], error: str) -> None:
        super().__init__(f"refused {json.dumps(request)}: {error}")
        self.request = request
        self.error = error


def _check_socket_path(path: Path) -> None:
    """Refuse a path that cannot be bound; remove a stale socket file left by a dead link."""
    if len(os.fsencode(path)) > MAX_SOCKET_PATH:
        raise ControlSocketError(path, f"longer than {MAX_SOCKET_PATH} bytes; choose a shorter path")
    try:
        mode = path.lstat().st_mode
    except FileNotFoundError:
        return
    if not stat.S_ISSOCK(mode):
        raise ControlSocketError(path, "exists and is not a socket; remove it or choose another path")
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:
        try:
            probe.connect(os.fspath(path))
        except ConnectionRefusedError:
            path.unlink()
            return
    raise ControlSocketError(path, "another process is listening on it")


class ControlServer:
    """Serve control requests for ``link`` on the Unix socket ``path`` (removed on close)."""

    def __init__(self, link: LinkEmulator, path: Path) -> None:
        self.link = link
        self.path = path
        self._server: asyncio.AbstractServer | None = None

    async def start(self) -> None:
        """Listen on :attr:`path`.

        Raises:
            ControlSocketError: the path is too long, taken by a live link, or not a socket.
        """
        _check_socket_path(self.path)
        self._server = await asyncio.start_unix_server(self._serve, os.fspath(self.path), limit=MAX_REQUEST)

    async def close(self) -> None:
        """Stop listening and remove the socket file."""
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()
            with contextlib.suppress(FileNotFoundError):
                self.path.unlink()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        try:
            while line := await reader.readline():
                writer.write(json.dumps(self.answer(line)).encode() + b"\n")
                await writer.drain()
        except ValueError:  # asyncio's LimitOverrunError on a line past MAX_REQUEST
            writer.write(
                json.dumps({"ok": False, "error": f"request longer than {MAX_REQUEST} bytes"}).encode() + b"\n"
            )
        except ConnectionError:
            pass  # the client left without reading its answer; nothing to tell it
        finally:
            writer.close()

    def answer(self, line: bytes) -> dict[str, Any]:
        """The answer to one request line (never raises: a bad request is answered as such)."""
        try:
            request = json.loads(line)
        except (UnicodeDecodeError, json.JSONDecodeError) as exc:
            return {"ok": False, "error": f"not JSON: {exc}"}
        if not isinstance(request, dict):
            return {"ok": False, "error": f"expected a JSON object, got {type(request).__name__}"}
        if request.get("stats") is True and len(request) == 1:
            return {"ok": True, "stats": self.link.stats().to_json()}
        if "outage" in request:
            return self._outage(request)
        return {
            "ok": False,
            "error": f"unknown request {json.dumps(request)[:200]}; expected "
            '{"outage": "hold"|"reset", "seconds": N} or {"stats": true}',
        }

    def _outage(self, request: dict[str, Any]) -> dict[str, Any]:
        kinds = {kind.value: kind for kind in OutageKind}
        kind, seconds = request.get("outage"), request.get("seconds")
        if set(request) != {"outage", "seconds"}:
            return {"ok": False, "error": f"an outage takes exactly the keys outage and seconds, got {sorted(request)}"}
        if kind not in kinds:
            return {"ok": False, "error": f"unknown outage {kind!r}; expected one of {sorted(kinds)}"}
        if (
            isinstance(seconds, bool)
            or not isinstance(seconds, (int, float))
            or not math.isfinite(seconds)
            or seconds < 0
        ):
            return {"ok": False, "error": f"seconds {seconds!r}: expected a number >= 0"}
        log.info("control: %s outage for %g s", kind, seconds)
        self.link.outage(Outage(kinds[kind], float(seconds)))
        return {"ok": True, "outage": kind, "seconds": seconds}


class JsonLineClient:
    """Blocking client of a JSON-line Unix socket: one connection, one request, one answer."""

    def __init__(self, path: Path | str, *, timeout: float = 10.0) -> None:
        self.path = Path(path)
        self.timeout = timeout

    def request(self, message: dict[str, Any]) -> dict[str, Any]:
        """Send one request; return the answer.

        Raises:
            LinkControlError: the server answered ``ok: false``.
            OSError: the socket is missing or nothing answered within the timeout.
        """
        with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
            sock.settimeout(self.timeout)
            sock.connect(os.fspath(self.path))
            sock.sendall(json.dumps(message).encode() + b"\n")
            with sock.makefile("rb") as answers:
                line = answers.readline()
        if not line:
            raise ConnectionError(f"{self.path} closed without answering {json.dumps(message)}")
        answer: dict[str, Any] = json.loads(line)
        if not answer.get("ok"):
            raise LinkControlError(message, str(answer.get("error")))
        return answer


class LinkControl(JsonLineClient):
    """Client of a link's control socket, for tests and benches."""

    def hold(self, seconds: float) -> None:
        """Hold all traffic for ``seconds`` from now."""
        self.request({"outage": "hold", "seconds": seconds})

    def reset(self, seconds: float) -> None:
        """Reset every connection now and refuse new ones for ``seconds``."""
        self.request({"outage": "reset", "seconds": seconds})

    def stats(self) -> LinkStats:
        """Bytes, stalls and outages so far."""
        return LinkStats.from_json(self.request({"stats": True})["stats"])
