"""The link's control socket: outages and stats at run time, and hostile requests refused."""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from caretaker.link import ControlServer, LinkConfig, LinkControl, LinkControlError, LinkEmulator
from caretaker.link.control import MAX_REQUEST, ControlSocketError

from .link_support import EchoTarget, exchange, run

#: s: an outage that outlasts the test, so a slow machine cannot see it end before the next call reads it.
OUTAGE_S = 600.0


def test_outages_and_stats_through_the_client(tmp_path: Path) -> None:
    path = tmp_path / "link.sock"

    async def body() -> None:
        async with EchoTarget() as target:
            link = LinkEmulator(LinkConfig.symmetric(delay=0.01), listen=("127.0.0.1", 0), target=target.address)
            control = ControlServer(link, path)
            async with link:
                await control.start()
                try:
                    client = LinkControl(path)
                    reader, writer = await asyncio.open_connection(*link.address)
                    assert await exchange(reader, writer, b"0123456789") == b"0123456789"
                    stats = await asyncio.to_thread(client.stats)
                    assert (stats.up_bytes, stats.down_bytes, len(stats.open_connections)) == (10, 10, 1)
                    assert stats.connections[0].peer.startswith("127.0.0.1:")

                    # outages far longer than the test: each is still on when the next call reads it
                    await asyncio.to_thread(client.hold, OUTAGE_S)
                    held = await asyncio.to_thread(client.stats)
                    assert held.holds == 1 and 0 < held.holding_for <= OUTAGE_S

                    await asyncio.to_thread(client.reset, OUTAGE_S)
                    with pytest.raises(ConnectionResetError):
                        await reader.read(1)
                    writer.close()
                    after = await asyncio.to_thread(client.stats)
                    assert after.resets == 1 and 0 < after.refusing_for <= OUTAGE_S and not after.open_connections
                finally:
                    await control.close()
        assert not path.exists()

    run(body())


@contextlib.asynccontextmanager
async def _controlled_link(path: Path) -> AsyncIterator[LinkEmulator]:
    """A link (to a port nobody needs) with its control socket at ``path``."""
    link = LinkEmulator(LinkConfig(), listen=("127.0.0.1", 0), target=("127.0.0.1", 9))
    control = ControlServer(link, path)
    async with link:
        await control.start()
        try:
            yield link
        finally:
            await control.close()


def _raw(path: Path, payload: bytes) -> dict[str, object]:
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as sock:
        sock.settimeout(10)
        sock.connect(str(path))
        sock.sendall(payload)
        with sock.makefile("rb") as answers:
            answer: dict[str, object] = json.loads(answers.readline())
            return answer


@pytest.mark.parametrize(
    "payload, complaint",
    [
        (b"nonsense\n", "not JSON"),
        (b"\xff\xfe\n", "not JSON"),
        (b"[1, 2]\n", "expected a JSON object, got list"),
        (b'{"stats": false}\n', "unknown request"),
        (b'{"outage": "pause", "seconds": 1}\n', "unknown outage 'pause'"),
        (b'{"outage": "hold", "seconds": -1}\n', "seconds -1: expected a number >= 0"),
        (b'{"outage": "hold", "seconds": true}\n', "seconds True"),
        (b'{"outage": "hold", "seconds": 1e999}\n', "seconds inf"),
        (b'{"outage": "hold"}\n', "exactly the keys outage and seconds"),
        (b"{" + b" " * MAX_REQUEST + b"}\n", f"longer than {MAX_REQUEST} bytes"),
    ],
)
def test_bad_requests_are_answered_and_change_nothing(tmp_path: Path, payload: bytes, complaint: str) -> None:
    path = tmp_path / "link.sock"

    async def body() -> None:
        async with _controlled_link(path) as link:
            answer = await asyncio.to_thread(_raw, path, payload)
            assert answer["ok"] is False and complaint in str(answer["error"])
            stats = link.stats()
            assert (stats.holds, stats.resets) == (0, 0)
            assert (await asyncio.to_thread(LinkControl(path).stats)).holds == 0  # still serving

    run(body())


def test_the_client_raises_the_links_refusal(tmp_path: Path) -> None:
    path = tmp_path / "link.sock"

    async def body() -> None:
        async with _controlled_link(path):
            with pytest.raises(LinkControlError, match="unknown outage") as error:
                await asyncio.to_thread(LinkControl(path).request, {"outage": "storm", "seconds": 1})
            assert error.value.request == {"outage": "storm", "seconds": 1}

    run(body())


def test_socket_paths_are_checked(tmp_path: Path) -> None:
    link = LinkEmulator(LinkConfig(), listen=("127.0.0.1", 0), target=("127.0.0.1", 9))
    stale = tmp_path / "stale.sock"
    with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as leftover:
        leftover.bind(str(stale))  # bound, never listening: what a killed link leaves behind
    plain = tmp_path / "plain"
    plain.write_text("not a socket")

    async def body() -> None:
        control = ControlServer(link, stale)
        await control.start()  # the stale file is replaced
        with pytest.raises(ControlSocketError, match="another process is listening"):
            await ControlServer(link, stale).start()
        await control.close()
        with pytest.raises(ControlSocketError, match="not a socket"):
            await ControlServer(link, plain).start()
        with pytest.raises(ControlSocketError, match="longer than"):
            await ControlServer(link, tmp_path / ("x" * 120)).start()

    run(body())
    assert plain.read_text() == "not a socket"
