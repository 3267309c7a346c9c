"""The long fuzz of the rosbridge server: 100,000+ hostile inputs against one bridge.

The same generators and watch as the fuzz tests (tests/rosbridge/hostile.py), for much longer,
from several clients at once.  The bridge runs with the tests' small quotas (so they are reached)
next to the tests' ROS peer node.  Input kinds, mixed at random from ``--seed``:

* mutated rosbridge messages for every op (NaN/Infinity, 4,000-digit numbers, lone surrogates,
  deep nesting, invalid names and types, values at and beyond every integer range); about 40 %
  are ``call_service``/``send_action_goal`` with a tracked id, which must be answered;
* raw WebSocket frames (unmasked, reserved bits and opcodes, oversized control frames,
  fragmented messages, pings, pongs, binary, close frames), each batch on a new connection:
  the connection must be served, or closed with a WebSocket protocol code when a frame calls
  for one;
* rosbridge ``fragment`` sequences (repeated, oversized, changing totals, huge numbers);
* connection abuse: connections dropped mid-frame, slowloris handshakes, clients that never
  read while flooding requests or pings, subscription floods.

Meanwhile a well-formed client calls ``/rosapi/get_ros_version`` every 20 ms: its slowest
round trip is reported as the worst event-loop stall.  Reported: inputs, crashes, tracebacks
logged, tracked requests answered, connections closed without a protocol reason, RSS start and
peak, worst stall, duration.

Usage: ``.venv/bin/python bench/bridge_fuzz.py [--inputs 100000] [--seed 20] [--clients 4]``
"""

from __future__ import annotations

import argparse
import os
import random
import socket
import sys
import threading
import time
from dataclasses import dataclass
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO / "tests"))

from caretaker.processes import ManagedProcess, caretaker, python  # noqa: E402
from rosbridge.hostile import (  # noqa: E402
    HOSTILE_LIMITS,
    BridgeLog,
    Watch,
    await_answers,
    hostile_frame,
    hostile_message,
    parses,
    serve_raw_frames,
)
from rosbridge.rosbridge_support import PING, FrameSocket, RawClient, bridge_url, frame, text  # noqa: E402
from support.ros_domain import claim_ros_domain  # noqa: E402

MiB = 2**20


@dataclass
class Tally:
    """What the attackers did and saw (guarded by a lock: several threads add to it)."""

    inputs: int = 0
    tracked: int = 0
    answered: int = 0
    unexpected_closes: int = 0
    connections: int = 0

    def __post_init__(self) -> None:
        self.lock = threading.Lock()

    def add(self, **counts: int) -> None:
        with self.lock:
            for name, value in counts.items():
                setattr(self, name, getattr(self, name) + value)


def messages(rng: random.Random, address: tuple[str, int], tally: Tally, count: int) -> None:
    """Mutated messages on one connection, batch by batch, each tracked request awaited."""
    client = RawClient(*address, max_size=None)
    client.send({"op": "set_level", "level": "error"})
    tally.add(connections=1)
    sent = 0
    try:
        while sent < count:
            wanted: set[str] = set()
            for _ in range(rng.randint(1, 8)):
                if rng.random() < 0.4:
                    request_id = f"t{rng.getrandbits(48)}"
                    message = hostile_message(rng, request_id)
                    if parses(message):
                        wanted.add(request_id)
                else:
                    message = hostile_message(rng)
                client.send(message)
                sent += 1
            tally.add(tracked=len(wanted), answered=len(wanted) - len(await_answers(client, wanted)))
        tally.add(inputs=sent)
    finally:
        client.close()


def raw_frames(rng: random.Random, address: tuple[str, int], tally: Tally, count: int) -> None:
    """Batches of raw frames, each on a new connection, ending with a tracked call."""
    sent = 0
    while sent < count:
        frames = [hostile_frame(rng) for _ in range(rng.randint(1, 8))]
        sent += len(frames)
        tally.add(connections=1, tracked=1)
        try:
            served = serve_raw_frames(address, frames)
        except (TimeoutError, ConnectionError):
            served = False
        # a connection refused as a frame called for answers for its request with its close code
        tally.add(answered=int(served), unexpected_closes=int(not served))
    tally.add(inputs=sent)


def fragments(rng: random.Random, address: tuple[str, int], tally: Tally, count: int) -> None:
    """rosbridge fragment sequences on one connection, each batch followed by a tracked call."""
    client = RawClient(*address, max_size=None)
    tally.add(connections=1)
    sent = 0
    try:
        while sent < count:
            for _ in range(rng.randint(1, 8)):
                client.send(
                    {
                        "op": "fragment",
                        "id": rng.choice(["a", "b", 7, "c" * 200]),
                        "num": rng.choice([-1, 0, 1, 2, 5, 2**31, 2**70]),
                        "total": rng.choice([-1, 0, 1, 2, 3, 6, 2**31, 2**70]),
                        "data": rng.choice(
                            [
                                "{",
                                "}",
                                '{"op":"fragment"}',
                                "x" * rng.randint(1, 400_000),
                                '{"op":"call_service","service":"/rosapi/get_time"}',
                            ]
                        ),
                    }
                )
                sent += 1
            request_id = f"f{sent}"
            client.send({"op": "call_service", "service": "/rosapi/get_ros_version", "id": request_id})
            tally.add(tracked=1, answered=1 - len(await_answers(client, {request_id})))
        tally.add(inputs=sent)
    finally:
        client.close()


def abuse(rng: random.Random, address: tuple[str, int], tally: Tally, count: int) -> None:
    """Connection-level attacks; each counts as one input."""
    for _ in range(count):
        kind = rng.choice(["drop mid-frame", "slowloris", "no reader", "ping flood", "subscription flood"])
        tally.add(connections=1)
        try:
            if kind == "slowloris":
                sock = socket.create_connection(address, timeout=5)
                sock.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n")  # and never the rest
                time.sleep(rng.random() * 0.2)  # holding the half-open handshake is the attack
                sock.close()
                continue
            client = FrameSocket(*address)
            client.sock.settimeout(0.5)
            try:
                if kind == "drop mid-frame":
                    call = text({"op": "call_service", "service": "/rosapi/topics"})
                    client.sock.sendall(call[: rng.randint(1, len(call) - 1)])
                elif kind == "no reader":
                    call = text({"op": "call_service", "service": "/rosapi/services", "fragment_size": 1024})
                    client.sock.sendall(call * rng.randint(100, 2000))
                elif kind == "ping flood":
                    client.sock.sendall(frame(PING, b"p" * 125) * rng.randint(1000, 20_000))
                else:
                    for number in range(30):
                        client.sock.sendall(
                            text(
                                {
                                    "op": "subscribe",
                                    "topic": f"/fuzz/sub_{number}",
                                    "type": "std_msgs/String",
                                    "fragment_size": 1024,
                                }
                            )
                        )
            except TimeoutError:
                pass  # the bridge stopped reading this client (backpressure)
            finally:
                client.close()
        except (ConnectionError, OSError):
            tally.add(unexpected_closes=1)
    tally.add(inputs=count)


def attacker(seed: int, address: tuple[str, int], tally: Tally, budget: int) -> None:
    rng = random.Random(seed)
    while budget > 0:
        kind = rng.random()
        chunk = min(budget, rng.randint(50, 400))
        if kind < 0.6:
            messages(rng, address, tally, chunk)
        elif kind < 0.85:
            raw_frames(rng, address, tally, chunk)
        elif kind < 0.95:
            fragments(rng, address, tally, chunk)
        else:
            chunk = min(budget, rng.randint(5, 20))
            abuse(rng, address, tally, chunk)
        budget -= chunk


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--inputs", type=int, default=100_000)
    parser.add_argument("--seed", type=int, default=20)
    parser.add_argument("--clients", type=int, default=4, help="attacking threads")
    args = parser.parse_args()
    env = dict(os.environ, ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", RMW_IMPLEMENTATION="rmw_fastrtps_cpp")
    env.setdefault("ROS_DOMAIN_ID", str(claim_ros_domain()))
    log = BridgeLog()
    peer = python(str(REPO / "tests" / "rosbridge" / "ros_peer.py"), env=env, name="ros-peer")
    bridge: ManagedProcess | None = None
    try:
        peer.wait_ready(60)
        bridge = caretaker("bridge", "--port", "0", "--service-timeout", "1", *HOSTILE_LIMITS, env=env, on_line=log)
        bridge.wait_ready(60)
        host, port = bridge_url(bridge).split("//")[1].rsplit(":", 1)
        address = (host, int(port))
        tally = Tally()
        started = time.monotonic()
        with Watch(bridge.proc.pid, address) as watch:
            threads = [
                threading.Thread(
                    target=attacker,
                    args=(args.seed * 1000 + n, address, tally, args.inputs // args.clients),
                    daemon=True,
                )
                for n in range(args.clients)
            ]
            for thread in threads:
                thread.start()
            for thread in threads:
                thread.join()
        duration = time.monotonic() - started
        rss_end = watch.process.memory_info().rss
        crashed = not bridge.running
        lines, tracebacks = log.snapshot()
        share = 100.0 * tally.answered / tally.tracked if tally.tracked else 100.0
        print(
            f"inputs {tally.inputs:,} on {tally.connections:,} connections in {duration:.0f} s "
            f"(seed {args.seed}, {args.clients} clients)"
        )
        print(f"crashes {int(crashed)}, tracebacks {tracebacks}, log lines {lines:,}")
        print(
            f"requests that must be answered: {tally.answered:,} of {tally.tracked:,} ({share:.2f} %); "
            f"connections closed without a protocol reason: {tally.unexpected_closes}"
        )
        print(
            f"RSS {watch.rss_start / MiB:.0f} MiB at start, peak {watch.rss_peak / MiB:.0f} MiB, "
            f"{rss_end / MiB:.0f} MiB at the end"
        )
        print(
            f"worst event-loop stall (a well-formed call every 20 ms, {watch.calls:,} calls): {watch.worst:.3f} s, "
            f"the bridge's CPU during one call at most {watch.busiest:.3f} s; unanswered {watch.unanswered}"
        )
        if log.first_traceback:
            print("the first traceback logged:\n" + "\n".join(log.first_traceback))
        ok = not crashed and tracebacks == 0 and share == 100.0 and watch.unanswered == 0
        return 0 if ok else 1
    finally:
        if bridge is not None:
            bridge.stop()
        peer.stop()


if __name__ == "__main__":
    sys.exit(main())
