"""A free TCP port on the loopback interface, for a server a test starts on a fixed port.

The port is free when this returns; a server started right after binds it. Prefer ``--port 0``
and reading the port the server reports where a server supports it: no other process can take
the port in between.
"""

from __future__ import annotations

import socket

__all__ = ["free_port"]


def free_port() -> int:
    """A TCP port on 127.0.0.1 that nothing listens on now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])
