"""Helpers of the link tests: a real TCP echo target and a way to run the async tests."""

from __future__ import annotations

import asyncio
import socket
import struct
from collections.abc import Coroutine
from typing import Any, TypeVar

T = TypeVar("T")


def run(coroutine: Coroutine[Any, Any, T], timeout: float = 120.0) -> T:
    """Run one async test body on a fresh event loop (the tests have no asyncio plugin)."""
    return asyncio.run(asyncio.wait_for(coroutine, timeout))


class EchoTarget:
    """A TCP echo server on loopback standing for the habitat side; records how connections end.

    ``endings`` gets "eof" when the relay closed its side with FIN and "reset" on RST.
    Writing ``b"!crash"`` alone makes the target reset it (a peer that crashed).
    """

    def __init__(self) -> None:
        self.endings: asyncio.Queue[str] = asyncio.Queue()
        self.accepted = 0
        self._server: asyncio.Server | None = None

    async def __aenter__(self) -> EchoTarget:
        self._server = await asyncio.start_server(self._echo, "127.0.0.1", 0)
        return self

    async def __aexit__(self, *exc_info: object) -> None:
        assert self._server is not None
        self._server.close()

    @property
    def address(self) -> tuple[str, int]:
        assert self._server is not None
        host, port = self._server.sockets[0].getsockname()[:2]
        return host, port

    async def _echo(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        self.accepted += 1
        try:
            while data := await reader.read(65536):
                if data == b"!crash":
                    sock = writer.get_extra_info("socket")
                    sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
                    writer.transport.abort()  # with linger 0: RST
                    return
                writer.write(data)
                await writer.drain()
            self.endings.put_nowait("eof")
        except ConnectionResetError:
            self.endings.put_nowait("reset")
        finally:
            writer.close()


async def exchange(reader: asyncio.StreamReader, writer: asyncio.StreamWriter, data: bytes) -> bytes:
    """Write ``data`` and read its echo."""
    writer.write(data)
    await writer.drain()
    return await reader.readexactly(len(data))
