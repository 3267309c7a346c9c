"""Hostile clients for the bridge and a watch on it while they attack.

Used by the fuzz tests (tests/rosbridge/test_hostile.py, test_fuzz.py) and by the long run in
bench/bridge_fuzz.py:

* :class:`BridgeLog` counts what the bridge logs (lines, tracebacks, anything that must never
  appear, such as the Zen of Python imported through a type name);
* :class:`Watch` keeps a well-formed client calling a service while an attack runs and records
  its worst round trip, the CPU the bridge spent while a call waited (a loop stalled by the
  attack's work shows there, where a crowded machine's slowness does not) and the bridge's RSS;
* :func:`hostile_message` and :func:`hostile_frame` make random mutated rosbridge messages and
  raw WebSocket frames from one seeded ``random.Random``.
"""

from __future__ import annotations

import json
import random
import re
import struct
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import psutil

from .rosbridge_support import BINARY, CLOSE, CONTINUATION, PING, PONG, TEXT, FrameSocket, RawClient, frame, text

MiB = 2**20
HOSTILE_LIMITS = (
    "--max-connections",
    "16",
    "--max-subscriptions",
    "20",
    "--max-total-subscriptions",
    "60",
    "--max-advertisements",
    "10",
    "--max-total-advertisements",
    "40",
    "--max-calls",
    "8",
    "--max-total-calls",
    "32",
    "--max-goals",
    "4",
    "--max-total-goals",
    "8",
    "--max-message-size",
    "1000000",
    "--max-pending-fragments",
    "4",
    "--max-total-fragment-bytes",
    "4000000",
    "--max-queued-bytes",
    str(4 * MiB),
    "--max-total-queued-bytes",
    str(16 * MiB),
    "--read-pause-bytes",
    str(READ_PAUSE_BYTES := 256 * 1024),
)
"""Small quotas, so the attacks reach them quickly (the bridge under fuzzing runs with these)."""
STALL_BOUND_S = 2.0
"""A generous sanity bound on the bridge's own work (CPU s) while one well-formed call waited for
its answer during an attack (not a performance claim). CPU, not the wait itself: on a machine
crowded by the rest of a test suite a call waits seconds for a core while the bridge does nothing."""
RSS_GROWTH_BOUND = 200 * MiB
"""What an attack may add to the bridge's RSS, far below the 480 MiB the unbounded bridge took."""
SOURCE_PATH = re.compile(r"[\w.-]+\.(?:py|c|cpp|h|so)(?::\d+)?\b|/(?:usr|opt|work|home)/")
ZEN = "Beautiful is better than ugly"
PROTOCOL_CLOSE_CODES = {1002, 1007, 1009}
ANSWERS = ("service_response", "action_result")


@dataclass
class BridgeLog:
    """What the bridge printed, fed line by line (``ManagedProcess(on_line=...)``)."""

    lines: int = 0
    tracebacks: int = 0
    forbidden: list[str] = field(default_factory=list)
    first_traceback: list[str] = field(default_factory=list)
    """The lines around the first traceback (the line before it and up to 40 after)."""
    _previous: str = ""
    _lock: threading.Lock = field(default_factory=threading.Lock)

    def __call__(self, name: str, line: str) -> None:
        with self._lock:
            self.lines += 1
            if "Traceback (most recent call last)" in line:
                self.tracebacks += 1
                if not self.first_traceback:
                    self.first_traceback.append(self._previous)
            if self.first_traceback and len(self.first_traceback) < 42:
                self.first_traceback.append(line)
            if ZEN in line:
                self.forbidden.append(line)
            self._previous = line

    def snapshot(self) -> tuple[int, int]:
        with self._lock:
            return self.lines, self.tracebacks


class Watch:
    """While an attack runs, a well-formed client calls ``service`` every ``period`` seconds;
    ``worst`` is its slowest round trip, ``busiest`` the most CPU the bridge spent during one
    round trip (what the call waited behind), and ``rss_peak`` the bridge's largest RSS seen."""

    def __init__(
        self, pid: int, address: tuple[str, int], service: str = "/rosapi/get_ros_version", period: float = 0.02
    ) -> None:
        self.process = psutil.Process(pid)
        self.address = address
        self.service = service
        self.period = period
        self.worst = 0.0
        self.busiest = 0.0
        self.calls = 0
        self.unanswered = 0
        self.rss_start = self.process.memory_info().rss
        self.rss_peak = self.rss_start
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="bridge-watch", daemon=True)

    def __enter__(self) -> Watch:
        self._client = RawClient(*self.address)
        self._call()  # a connected, warmed-up client before the attack begins
        self.worst = self.busiest = 0.0
        self._thread.start()
        return self

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        self._thread.join(30)
        self._call()  # the bridge still serves once the attack is over
        self._client.close()

    def _call(self) -> None:
        request_id = f"watch {self.calls}"
        cpu = self._cpu()
        started = time.monotonic()
        self._client.send({"op": "call_service", "service": self.service, "id": request_id})
        try:
            while self._client.receive(timeout=30).get("id") != request_id:
                pass
        except TimeoutError:
            self.unanswered += 1
        self.worst = max(self.worst, time.monotonic() - started)
        self.busiest = max(self.busiest, self._cpu() - cpu)
        self.calls += 1

    def _cpu(self) -> float:
        times = self.process.cpu_times()
        return float(times.user + times.system)

    def _run(self) -> None:
        while not self._stop.wait(self.period):
            self._call()
            self.rss_peak = max(self.rss_peak, self.process.memory_info().rss)

    def check(self, stall_bound: float = STALL_BOUND_S, rss_growth: int = RSS_GROWTH_BOUND) -> None:
        """Assert the bounds (after the attack, with the watch stopped)."""
        assert self.unanswered == 0, f"{self.unanswered} of {self.calls} well-formed calls were not answered"
        assert self.busiest < stall_bound, (
            f"a well-formed call waited while the bridge worked {self.busiest:.2f} s of CPU during the attack "
            f"(the slowest call took {self.worst:.2f} s)"
        )
        grown = self.rss_peak - self.rss_start
        assert grown < rss_growth, f"the bridge's RSS grew by {grown / MiB:.0f} MiB during the attack"


# --- random hostile input ------------------------------------------------------------------------

OPS = [
    "advertise",
    "unadvertise",
    "publish",
    "subscribe",
    "unsubscribe",
    "call_service",
    "service_response",
    "advertise_service",
    "unadvertise_service",
    "send_action_goal",
    "cancel_action_goal",
    "action_feedback",
    "action_result",
    "advertise_action",
    "unadvertise_action",
    "fragment",
    "set_level",
    "auth",
    "png",
    "status",
    "",
    "teleport",
]
NAMES = [
    "/fuzz/a",
    "/fuzz/b",
    "fuzz",
    "",
    "/",
    "//x",
    "/1a",
    "/a/",
    "/ä/ü",
    "/a\ud800",
    "/fuzz/" + "n" * 300,
    "/rosapi/topics",
    "/rosapi/services",
    "/rosapi/set_param",
    "/rosapi/nope",
    "/peer/set_bool",
    "/rosbridge/connection_stats",
    "/rosbridge_websocket/set_parameters",
    "/peer/follow",
    "/fuzz/~x",
]
TYPES = [
    "std_msgs/String",
    "std_msgs/msg/Int8",
    "std_msgs/msg/UInt32",
    "std_msgs/msg/Header",
    "std_srvs/srv/SetBool",
    "std_srvs/Trigger",
    "caretaker_sim_msgs/action/FollowJointTrajectory",
    "sensor_msgs/msg/CameraInfo",
    "this/msg/Zen",
    "os/msg/System",
    "../../etc/passwd",
    "std_msgs/msg/Nope",
    "",
    "std_msgs/msg/String/x",
]
FIELDS = [
    "topic",
    "type",
    "msg",
    "id",
    "service",
    "args",
    "values",
    "result",
    "action",
    "action_type",
    "throttle_rate",
    "queue_length",
    "queue_size",
    "fragment_size",
    "compression",
    "level",
    "data",
    "num",
    "total",
    "timeout",
    "latch",
    "feedback",
    "status",
    "mac",
    "t",
    "end",
    "token",
]
NASTY = [
    "NaN",
    "Infinity",
    "-Infinity",
    "1e400",
    "-0",
    "1" * 4000,
    "1" * 5000,
    "9" * 400,
    "2147483648",
    "4294967296",
    "-1",
    "128",
    "18446744073709551616",
    '"\\ud800"',
    '"\\udc00x"',
    '"é"',
    '"\\u0000"',
    "[" * 3000 + "]" * 3000,
    "{}",
    "[]",
    "null",
    "true",
    '"' + "x" * 70_000 + '"',
]


def _value(rng: random.Random, depth: int = 0) -> str:
    """A JSON value as text (so NaN, huge ints and lone surrogates can be spelled)."""
    roll = rng.random()
    if roll < 0.25:
        return rng.choice(NASTY)
    if roll < 0.45:
        return json.dumps(rng.choice(NAMES + TYPES))
    if roll < 0.6:
        return str(rng.choice([0, 1, -1, 127, 128, 255, 256, 2**31, 2**32, 2**63, 2**64, rng.randint(-(10**6), 10**6)]))
    if roll < 0.7:
        return rng.choice(["0.5", "1e308", "3.5e38", "-3.5e38", "1.5"])
    if roll < 0.8 or depth > 3:
        return json.dumps("".join(rng.choice('ab/_\\"é\u2028') for _ in range(rng.randint(0, 12))))
    if roll < 0.9:
        return "[" + ",".join(_value(rng, depth + 1) for _ in range(rng.randint(0, 4))) + "]"
    keys = rng.sample(FIELDS + ["data", "sec", "nanosec", "stamp", "header", "k", "uuid", "seq"], rng.randint(0, 4))
    return "{" + ",".join(f"{json.dumps(k)}:{_value(rng, depth + 1)}" for k in keys) + "}"


def hostile_message(rng: random.Random, request_id: str | None = None) -> str:
    """One mutated rosbridge message as JSON text: an op with fields from the pools above.
    With ``request_id``, a ``call_service`` or ``send_action_goal`` carrying that id (whatever
    else it holds, it must be answered)."""
    if request_id is not None:
        op = rng.choice(["call_service", "send_action_goal"])
        fields = {"id": json.dumps(request_id), "service" if op == "call_service" else "action": _name(rng)}
    else:
        op = rng.choice(OPS)
        fields = {}
    for name in rng.sample(FIELDS, rng.randint(0, 5)):
        if name in fields:
            continue
        if name in ("topic", "service", "action") and rng.random() < 0.7:
            fields[name] = _name(rng)
        elif name in ("type", "action_type") and rng.random() < 0.7:
            fields[name] = json.dumps(rng.choice(TYPES))
        else:
            fields[name] = _value(rng)
    return "{" + ",".join([f'"op":{json.dumps(op)}'] + [f"{json.dumps(k)}:{v}" for k, v in fields.items()]) + "}"


def _name(rng: random.Random) -> str:
    return json.dumps(rng.choice(NAMES)) if rng.random() < 0.8 else _value(rng)


SERVED, PROTOCOL_ERROR, CLOSING = "served", "protocol error", "closing"


def hostile_frame(rng: random.Random) -> tuple[bytes, str]:
    """One raw WebSocket frame (masked unless the mutation says otherwise) and what it may do:
    :data:`SERVED`, :data:`PROTOCOL_ERROR` (the bridge may close with 1002, 1007 or 1009) or
    :data:`CLOSING` (a close frame: the bridge answers it with some close code).  The payload is
    often a hostile message."""
    roll = rng.random()
    if roll < 0.55:
        # a lone surrogate written raw is invalid UTF-8: 1007
        return frame(TEXT, hostile_message(rng).encode("utf-8", "surrogatepass")), PROTOCOL_ERROR
    if roll < 0.65:
        return frame(PING, rng.randbytes(rng.randint(0, 125))), SERVED
    if roll < 0.7:
        return frame(PONG, rng.randbytes(rng.randint(0, 125))), SERVED
    if roll < 0.78:
        body = hostile_message(rng).encode("utf-8", "surrogatepass")
        cut = rng.randint(0, len(body))
        return frame(TEXT, body[:cut], fin=False) + frame(CONTINUATION, body[cut:]), PROTOCOL_ERROR
    if roll < 0.84:
        return frame(BINARY, rng.randbytes(rng.randint(0, 300))), SERVED
    if roll < 0.88:
        return frame(TEXT, b'{"op":"set_level","level":"error"}', masked=False), PROTOCOL_ERROR
    if roll < 0.92:
        return frame(rng.choice([0x3, 0x4, 0xB, 0xF]), b"reserved"), PROTOCOL_ERROR
    if roll < 0.95:
        return frame(TEXT, b'{"op":"x"}', rsv=rng.choice([1, 2, 4])), PROTOCOL_ERROR
    if roll < 0.98:
        return frame(PING, rng.randbytes(126)), PROTOCOL_ERROR  # a control frame over 125 bytes
    return frame(CLOSE, struct.pack("!H", rng.choice([1000, 1005, 999, 4999, 65535])) + b"bye"), CLOSING


def parses(message: str) -> bool:
    """Whether ``message`` is JSON to Python's parser, which the bridge uses too (a message that
    does not parse cannot be answered by its id: only a status says what was wrong)."""
    try:
        json.loads(message)
        return True
    except (ValueError, RecursionError):
        return False


def await_answers(client: RawClient, wanted: set[str], timeout: float = 20.0) -> set[str]:
    """Read until every id in ``wanted`` was answered (``service_response``/``action_result``;
    other frames skipped, fragmented answers reassembled), or nothing came for ``timeout``;
    returns the ids still unanswered.  No failure text may name a server file."""
    wanted = set(wanted)
    parts: dict[str, dict[int, str]] = {}
    while wanted:
        try:
            message = client.receive(timeout=timeout)
        except TimeoutError:
            break
        if message.get("op") == "fragment":  # a fuzzed fragment_size may have split answers
            received = parts.setdefault(message["id"], {})
            received[message["num"]] = message["data"]
            if len(received) < message["total"]:
                continue
            message = json.loads("".join(received[i] for i in range(message["total"])))
        reason = message.get("values") if message.get("result") is False else message.get("msg")
        assert not (isinstance(reason, str) and SOURCE_PATH.search(reason)), message
        if message.get("op") in ANSWERS:
            wanted.discard(message.get("id"))
    return wanted


def serve_raw_frames(address: tuple[str, int], frames: list[tuple[bytes, str]]) -> bool:
    """Send ``frames`` (from :func:`hostile_frame`) and a call on a new connection; True if the
    call is answered, or the connection is closed as one of the frames called for."""
    sock = FrameSocket(*address)
    try:
        sock.sock.sendall(
            b"".join(data for data, _ in frames)
            + text({"op": "call_service", "service": "/rosapi/get_time", "id": "last"})
        )
        while True:
            opcode, payload = sock.read_frame()
            if opcode == CLOSE:
                code = int.from_bytes(payload[:2], "big")
                effects = {effect for _, effect in frames}
                return CLOSING in effects or (code in PROTOCOL_CLOSE_CODES and PROTOCOL_ERROR in effects)
            if opcode == TEXT and json.loads(payload).get("id") == "last":
                return True
    finally:
        sock.close()
