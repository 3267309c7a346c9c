"""Serving HTTP as the ground's servers do (``caretaker serve``, ``caretaker agent --listen``).

Loopback unless told otherwise; beyond loopback only over TLS, or with ``--insecure`` where the
network is encrypted otherwise, because what crosses it (passwords, session cookies, agents'
bearer tokens) must not cross in clear text. The socket is bound before anything else starts, so
a port that is taken is refused at once, and ``READY <name> <url>`` is printed only once it accepts.
"""

from __future__ import annotations

import contextlib
import ipaddress
import socket
import ssl
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import uvicorn

__all__ = ["Listener", "loopback", "serve", "tls_problem"]


def loopback(address: str) -> bool:
    if address == "localhost":
        return True
    try:
        return ipaddress.ip_address(address).is_loopback
    except ValueError:
        return False  # a host name: it may resolve to anything


def tls_problem(address: str, certfile: Path | None, keyfile: Path | None, insecure: bool, secrets: str) -> str | None:
    """Why these TLS options cannot serve ``address`` (None: they can); ``secrets``: what would cross in clear."""
    if (certfile is None) != (keyfile is None):
        return "--certfile and --keyfile go together"
    if certfile is None or keyfile is None:
        if loopback(address) or insecure:
            return None
        return (
            f"--address {address} reaches beyond this machine, and {secrets} must not cross a network in clear "
            "text: give --certfile and --keyfile (TLS), or --insecure if the network is encrypted otherwise "
            "(VPN, a TLS proxy on this host)"
        )
    try:
        ssl.create_default_context(ssl.Purpose.CLIENT_AUTH).load_cert_chain(certfile, keyfile)
    except ssl.SSLError as exc:  # before OSError, of which it is a kind
        reason = exc.reason or exc
        return f"--certfile {certfile} and --keyfile {keyfile} are not a usable PEM certificate and key: {reason}"
    except OSError as exc:
        return f"cannot read the TLS files: {exc.strerror or exc} ({exc.filename or certfile})"
    return None


@dataclass(frozen=True)
class Listener:
    """A bound socket and the URL it answers at."""

    sock: socket.socket
    url: str

    @classmethod
    def bind(cls, address: str, port: int, *, tls: bool) -> Listener:
        """Bind ``address:port`` (0: any free port). OSError when it cannot be bound."""
        family = socket.AF_INET6 if ":" in address else socket.AF_INET
        sock = socket.socket(family, socket.SOCK_STREAM)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            sock.bind((address, port))
        except OSError:
            sock.close()
            raise
        host, bound = sock.getsockname()[:2]
        scheme = "https" if tls else "http"
        return cls(sock, f"{scheme}://[{host}]:{bound}" if family == socket.AF_INET6 else f"{scheme}://{host}:{bound}")

    @property
    def port(self) -> int:
        return int(self.sock.getsockname()[1])


class _AnnouncingServer(uvicorn.Server):
    """uvicorn, announcing readiness after its sockets accept connections."""

    def __init__(self, config: uvicorn.Config, ready: str) -> None:
        super().__init__(config)
        self.ready = ready

    async def startup(self, sockets: list[socket.socket] | None = None) -> None:
        await super().startup(sockets=sockets)
        if not self.should_exit:
            print(self.ready, flush=True)


def serve(app: Any, listener: Listener, name: str, certfile: Path | None, keyfile: Path | None, **config: Any) -> None:
    """Serve ``app`` on ``listener`` until stopped (Ctrl-C ends it quietly); ``READY name url`` once it accepts."""
    settings = uvicorn.Config(app, log_level="warning", ssl_certfile=certfile, ssl_keyfile=keyfile, **config)
    with contextlib.suppress(KeyboardInterrupt):
        _AnnouncingServer(settings, f"READY {name} {listener.url}").run(sockets=[listener.sock])
