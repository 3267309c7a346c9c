"""The link emulator relaying real TCP connections: delay, order, bandwidth, loss, outages, counts.

Timing is asserted only as lower bounds (what the link must at least cost); the rest is bytes,
order and the seeded loss pattern.
"""

from __future__ import annotations

import asyncio
import os

import pytest

from caretaker.link import Direction, LinkConfig, LinkEmulator, Outage, OutageKind, TcpModel

from .link_support import EchoTarget, exchange, run

MSS = 1448


def _link(config: LinkConfig, target: EchoTarget) -> LinkEmulator:
    return LinkEmulator(config, listen=("127.0.0.1", 0), target=target.address)


def test_delay_is_a_lower_bound_and_a_new_connection_costs_a_handshake() -> None:
    async def body() -> None:
        delay = 0.15
        async with EchoTarget() as target, _link(LinkConfig.symmetric(delay=delay), target) as link:
            loop = asyncio.get_running_loop()
            start = loop.time()
            reader, writer = await asyncio.open_connection(*link.address)
            assert await exchange(reader, writer, b"ping") == b"ping"
            first = loop.time() - start
            start = loop.time()
            assert await exchange(reader, writer, b"pong") == b"pong"
            second = loop.time() - start
            writer.close()
        assert first >= 4 * delay  # SYN/SYN-ACK round trip, then the request and its answer
        assert second >= 2 * delay

    run(body())


def test_jitter_never_reorders_bytes() -> None:
    async def body() -> None:
        config = LinkConfig.symmetric(delay=0.01, jitter=0.05, seed=4)
        async with EchoTarget() as target, _link(config, target) as link:
            reader, writer = await asyncio.open_connection(*link.address)
            sent = b"".join(f"{index:05d};".encode() for index in range(400))
            for index in range(0, len(sent), 6):
                writer.write(sent[index : index + 6])
                await writer.drain()
            bulk = os.urandom(200_000)
            writer.write(bulk)
            assert await reader.readexactly(len(sent)) == sent
            assert await reader.readexactly(len(bulk)) == bulk
            writer.close()

    run(body())


def test_bandwidth_serialises_segments_with_their_headers_and_is_shared() -> None:
    async def body() -> tuple[float, float]:
        kbps, size = 64, 4000
        segments = -(-size // MSS)
        line_time = (size + 52 * segments) * 8 / (kbps * 1000)
        config = LinkConfig.symmetric(up_kbps=kbps, down_kbps=kbps)
        async with EchoTarget() as target, _link(config, target) as link:
            loop = asyncio.get_running_loop()
            start = loop.time()
            reader, writer = await asyncio.open_connection(*link.address)
            await exchange(reader, writer, b"x" * size)
            alone = loop.time() - start
            assert alone >= line_time

            async def one() -> None:
                conn_reader, conn_writer = await asyncio.open_connection(*link.address)
                await exchange(conn_reader, conn_writer, b"y" * size)
                conn_writer.close()

            start = loop.time()
            await asyncio.gather(one(), one())
            together = loop.time() - start
            writer.close()
            await link.wait_idle()
            stats = link.stats()
        assert together >= 2 * line_time  # two connections share one uplink
        assert stats.up_bytes == stats.down_bytes == 3 * size
        return alone, together

    run(body())


def _segment_starts(message: int, count: int) -> list[int]:
    """Where the relay cuts ``count`` messages of ``message`` bytes read one at a time."""
    starts = {index * message for index in range(count)}
    starts |= set(range(MSS, message * count, MSS))
    return sorted(starts)


def test_loss_stalls_follow_the_seed() -> None:
    message, count = 200, 40

    async def lockstep(seed: int) -> tuple[int, int, float]:
        config = LinkConfig.symmetric(loss=0.15, seed=seed)
        async with EchoTarget() as target, _link(config, target) as link:
            loop = asyncio.get_running_loop()
            reader, writer = await asyncio.open_connection(*link.address)
            start = loop.time()
            for index in range(count):  # one message in flight at a time: the relay reads each alone
                payload = f"{index:03d}".encode().ljust(message, b".")
                assert await exchange(reader, writer, payload) == payload
            elapsed = loop.time() - start
            writer.close()
            await link.wait_idle()
            stats = link.stats()
        return stats.up_stalls, stats.down_stalls, elapsed

    for seed in (5, 6):
        model = TcpModel(LinkConfig.symmetric(loss=0.15, seed=seed))
        fates = {
            direction: [model.fate(direction, 1, start) for start in _segment_starts(message, count)]
            for direction in Direction
        }
        predicted = {direction: sum(1 for fate in fates[direction] if fate.losses) for direction in Direction}
        up, down, elapsed = run(lockstep(seed))
        assert (up, down) == (predicted[Direction.UP], predicted[Direction.DOWN])
        assert up + down > 0
        # in lockstep each message waits out its longest stall each way, one message after another
        starts = _segment_starts(message, count)
        waits = sum(
            max(fate.stall for start, fate in zip(starts, fates[direction], strict=False) if start // message == index)
            for direction in Direction
            for index in range(count)
        )
        assert elapsed >= waits


def test_a_hold_delivers_late_and_keeps_the_connection() -> None:
    async def body() -> None:
        async with EchoTarget() as target, _link(LinkConfig.symmetric(delay=0.05), target) as link:
            loop = asyncio.get_running_loop()
            reader, writer = await asyncio.open_connection(*link.address)
            assert await exchange(reader, writer, b"before") == b"before"
            link.hold(1.0)
            start = loop.time()
            assert await exchange(reader, writer, b"during") == b"during"
            assert loop.time() - start >= 1.0 + 0.05  # sent after the hold, then the delay back
            assert await exchange(reader, writer, b"after") == b"after"
            stats = link.stats()
            writer.close()
        assert stats.holds == 1 and len(stats.open_connections) == 1 and target.accepted == 1

    run(body())


def test_a_scheduled_hold_delays_new_connections_too() -> None:
    async def body() -> None:
        config = LinkConfig.symmetric(outages=(Outage(OutageKind.HOLD, 0.8, at=0.0),))
        async with EchoTarget() as target, _link(config, target) as link:
            loop = asyncio.get_running_loop()
            start = loop.time()
            reader, writer = await asyncio.open_connection(*link.address)
            assert await exchange(reader, writer, b"hello") == b"hello"
            assert loop.time() - start >= 0.8
            writer.close()

    run(body())


def test_a_reset_closes_both_ends_and_refuses_new_connections_for_its_length() -> None:
    async def body() -> None:
        async with EchoTarget() as target, _link(LinkConfig.symmetric(delay=0.02), target) as link:
            reader, writer = await asyncio.open_connection(*link.address)
            assert await exchange(reader, writer, b"hello") == b"hello"
            link.reset(1.0)
            with pytest.raises(ConnectionResetError):
                await reader.read(10)
            assert await target.endings.get() == "reset"
            writer.close()

            refused_reader, refused_writer = await asyncio.open_connection(*link.address)
            with pytest.raises(ConnectionResetError):
                await refused_reader.read(10)
            refused_writer.close()
            stats = link.stats()
            assert stats.resets == 1 and stats.refused == 1 and stats.refusing_for > 0
            assert stats.connections[0].ended_by == "reset by outage"

            await asyncio.sleep(stats.refusing_for)  # the outage's own length, read from the link
            reader, writer = await asyncio.open_connection(*link.address)
            assert await exchange(reader, writer, b"back") == b"back"
            writer.close()

    run(body())


def test_a_peer_reset_crosses_the_link() -> None:
    async def body() -> None:
        async with EchoTarget() as target, _link(LinkConfig.symmetric(delay=0.05), target) as link:
            reader, writer = await asyncio.open_connection(*link.address)
            writer.write(b"!crash")
            with pytest.raises(ConnectionResetError):
                await reader.read(10)
            writer.close()
            await link.wait_idle()
            assert link.stats().connections[0].ended_by == "reset by a peer"

    run(body())


def test_a_refusing_target_resets_the_client() -> None:
    async def body() -> None:
        async with EchoTarget() as target:
            address = target.address
        link = LinkEmulator(LinkConfig(), listen=("127.0.0.1", 0), target=address)  # nobody listens there now
        async with link:
            reader, writer = await asyncio.open_connection(*link.address)
            with pytest.raises(ConnectionResetError):
                await reader.read(10)
            writer.close()
            await link.wait_idle()
            ended_by = link.stats().connections[0].ended_by
        assert ended_by is not None and ended_by.startswith("error: target 127.0.0.1:") and "refused" in ended_by

    run(body())


def test_bytes_are_counted_per_connection_and_in_total() -> None:
    async def body() -> None:
        sizes = [1000, 20_000, 5]
        async with EchoTarget() as target, _link(LinkConfig(mss=512, window=2048), target) as link:
            for size in sizes:
                reader, writer = await asyncio.open_connection(*link.address)
                assert await exchange(reader, writer, os.urandom(size)) is not None
                writer.write_eof()
                assert await reader.read() == b""  # the target's FIN came back through the link
                writer.close()
                assert await target.endings.get() == "eof"
            await link.wait_idle()
            stats = link.stats()
        assert [(c.up_bytes, c.down_bytes) for c in stats.connections] == [(size, size) for size in sizes]
        assert [c.ended_by for c in stats.connections] == ["closed"] * 3
        assert stats.up_bytes == stats.down_bytes == sum(sizes)
        assert all(c.closed is not None and c.closed >= c.opened for c in stats.connections)

    run(body())


def test_closing_the_link_resets_open_connections() -> None:
    async def body() -> None:
        async with EchoTarget() as target:
            link = _link(LinkConfig(), target)
            async with link:
                reader, writer = await asyncio.open_connection(*link.address)
                assert await exchange(reader, writer, b"x") == b"x"
            with pytest.raises(ConnectionResetError):
                await reader.read(10)
            writer.close()
            assert await target.endings.get() == "reset"
            assert link.stats().connections[0].ended_by == "link closed"

    run(body())
