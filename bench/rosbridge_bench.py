"""Benchmark: this rosbridge server vs the Rust ``rosbridge-server-rs``, side by side, raw JSON.

Both servers run in this one invocation against the same ROS echo node (a separate process),
driven by bare WebSocket clients (no client library in the loop):

* round trip through the echo node, 32 messages in flight, at 64 B, 1 KiB and 64 KiB:
  messages/s and the share lost;
* RTT percentiles (p50/p95/p99) with 1 message in flight (64 B);
* ``call_service`` with 32 calls in flight: calls/s and RTT percentiles;
* fan-out of a 100 Hz topic to 1, 10 and 50 subscribers: messages lost, p95 delivery latency;
* server RSS (MiB) at the end.

Usage: ``.venv/bin/python bench/rosbridge_bench.py [--quick] [--only caretaker|rust] [--soak SECONDS]
[--peer-dds-profile] [--baseline DIR]`` (``--soak 600`` runs echo traffic and client churn for ten
minutes and reports RSS instead; ``--peer-dds-profile`` gives the peer the bridge's Fast DDS
profile too; ``--baseline DIR`` adds a third server, the bridge of another version whose
``python/`` folder is in DIR, e.g. ``git archive main python | tar -x -C DIR``, interleaved with
the others in the same run, to compare a change with the code before it).
The Rust peer runs as the notes' recipe says: a ``librmw_implementation.so`` symlink to the
venv's ``librmw_fastrtps_cpp.so`` on ``LD_LIBRARY_PATH``, ``LD_PRELOAD`` of libpython,
``--no-rosapi``, bound to loopback; its wheel ships the binary without the execute bit, so it
is started through the dynamic loader.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import re
import socket
import statistics
import subprocess
import sys
import sysconfig
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parents[1]
VENV = REPO / ".venv"
IN_FLIGHT = 32
WARM_UP = 200  # unrecorded round trips per server before measuring
ROUNDS = 5  # rounds of each echo measurement (alternating which server goes first)
SIZES = {"64 B": 64, "1 KiB": 1024, "64 KiB": 65536}
FANOUT_CLIENTS = (1, 10, 50)
FANOUT_HZ = 100
SERVERS = ["caretaker", "rust"]


# --- the ROS echo node (runs as its own process: ``--echo-node``) --------------------------------


def echo_node() -> int:

    import rclpy
    from rclpy.executors import ExternalShutdownException
    from rclpy.experimental import EventsExecutor
    from rclpy.node import Node
    from rclpy.qos import QoSProfile
    from std_msgs.msg import String
    from std_srvs.srv import SetBool, Trigger

    class EchoNode(Node):
        """Per server name N: echoes /bench/N/in to /bench/N/out, answers /bench/N/echo_srv, and
        publishes a 100 Hz burst on /bench/N/fanout when /bench/N/start_fanout is called."""

        def __init__(self, names: list[str]) -> None:
            super().__init__("bench_echo")
            deep = QoSProfile(depth=1000)
            self.bursts: dict[str, list[int]] = {}
            self.fanouts = {}
            for name in names:
                out = self.create_publisher(String, f"/bench/{name}/out", deep)
                self.create_subscription(String, f"/bench/{name}/in", out.publish, deep)
                self.create_service(SetBool, f"/bench/{name}/echo_srv", self.service_callback, qos_profile=deep)
                self.fanouts[name] = self.create_publisher(String, f"/bench/{name}/fanout", deep)
                self.bursts[name] = [0, 0]  # next sequence, remaining
                self.create_service(
                    Trigger,
                    f"/bench/{name}/start_fanout",
                    lambda request, response, name=name: self.start_callback(name, response),
                )
            self.timer = self.create_timer(1.0 / FANOUT_HZ, self.fanout_callback)

        def service_callback(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
            response.success = request.data
            response.message = "echo"
            return response

        def start_callback(self, name: str, response: Trigger.Response) -> Trigger.Response:
            burst = self.bursts[name]
            response.success = self.fanouts[name].get_subscription_count() > 0 and burst[1] == 0
            if response.success:
                burst[0], burst[1] = 0, int(os.environ["BENCH_FANOUT_COUNT"])
            return response

        def fanout_callback(self) -> None:
            for name, burst in self.bursts.items():
                if burst[1] > 0:
                    burst[1] -= 1
                    self.fanouts[name].publish(String(data=f"{burst[0]} {time.time()}"))
                    burst[0] += 1

    rclpy.init()
    node = EchoNode(os.environ.get("BENCH_SERVERS", ",".join(SERVERS)).split(","))
    executor = EventsExecutor()
    executor.add_node(node)
    print("READY echo", flush=True)
    try:
        while rclpy.ok():
            executor.spin_once(timeout_sec=0.5)
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


# --- starting servers ----------------------------------------------------------------------------


def free_port() -> int:
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def wait_for_line(process: subprocess.Popen, pattern: str, timeout: float) -> str:
    deadline = time.monotonic() + timeout
    assert process.stdout is not None
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            raise RuntimeError(f"process exited with {process.wait()} before printing {pattern!r}")
        if re.search(pattern, line):
            return line
    raise RuntimeError(f"no {pattern!r} within {timeout} s")


def wait_for_port(port: int, timeout: float = 30.0) -> None:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), 0.5).close()
            return
        except OSError:
            time.sleep(0.05)  # the peer prints no readiness line; poll its port
    raise RuntimeError(f"nothing listens on {port} after {timeout} s")


def start_caretaker(env: dict[str, str], baseline: Path | None = None) -> tuple[subprocess.Popen, int]:
    """``caretaker bridge`` of this checkout, or the one under ``baseline/python``."""
    argv = [str(VENV / "bin" / "caretaker"), "bridge"]
    if baseline is not None:
        env = dict(env, PYTHONPATH=str(baseline / "python"))  # found before this checkout's editable install
        argv = [sys.executable, "-m", "bridge.rosbridge.server"]
    process = subprocess.Popen(
        [*argv, "--port", "0", "--log-level", "WARNING"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    line = wait_for_line(process, r"^READY bridge", 60)
    return process, int(line.strip().rsplit(":", 1)[1])


def start_rust(env: dict[str, str], workdir: Path, dds_profile: bool = False) -> tuple[subprocess.Popen, int]:
    """The Rust peer as the notes' recipe runs it; with ``dds_profile``, under the Fast DDS
    profile ``caretaker bridge`` loads for itself, to tell its DDS settings from the servers."""
    import rosbridge_server_rs

    from bridge.rosbridge.server import DDS_PROFILE, DDS_PROFILE_ENV

    binary = Path(rosbridge_server_rs.__file__).with_name("rosbridge_server_rs_jazzy")
    link = workdir / "librmw_implementation.so"
    if not link.exists():
        link.symlink_to(VENV / "lib" / "librmw_fastrtps_cpp.so")
    libpython = Path(sysconfig.get_config_var("LIBDIR")) / sysconfig.get_config_var("LDLIBRARY")
    env = dict(
        env,
        ROS_DISTRO="jazzy",
        LD_LIBRARY_PATH=f"{workdir}:{env.get('LD_LIBRARY_PATH', '')}",
        LD_PRELOAD=str(libpython),
    )
    if dds_profile:
        env[DDS_PROFILE_ENV] = str(DDS_PROFILE)
    port = free_port()
    loader = "/lib64/ld-linux-x86-64.so.2"
    process = subprocess.Popen(
        [loader, str(binary), "--no-rosapi", "--bind", f"127.0.0.1:{port}", "--log-level", "warn"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    wait_for_port(port)
    return process, port


def stop(process: subprocess.Popen) -> None:
    process.send_signal(subprocess.signal.SIGINT)
    try:
        process.wait(10)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait(10)


# --- measurements -------------------------------------------------------------------------------


@dataclass
class Results:
    server: str
    figures: dict[str, Any] = field(default_factory=dict)


def percentile(values: list[float], share: float) -> float:
    if not values:
        return float("nan")
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, int(share * len(ordered)))]


async def connect(port: int) -> Any:
    from websockets.asyncio.client import connect as ws_connect

    return await ws_connect(f"ws://127.0.0.1:{port}", max_size=None, compression=None, open_timeout=30)


async def echo_setup(port: int, name: str) -> Any:
    ws = await connect(port)
    await ws.send(json.dumps({"op": "advertise", "topic": f"/bench/{name}/in", "type": "std_msgs/msg/String"}))
    await ws.send(
        json.dumps(
            {"op": "subscribe", "topic": f"/bench/{name}/out", "type": "std_msgs/msg/String", "queue_length": 1000}
        )
    )
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:  # until ROS matched both ends: the first echo
        await ws.send(json.dumps({"op": "publish", "topic": f"/bench/{name}/in", "msg": {"data": "warm-up"}}))
        try:
            await asyncio.wait_for(ws.recv(), 0.2)
            break
        except TimeoutError:
            continue
    else:
        raise RuntimeError("no echo within 30 s")
    while True:  # drain leftover warm-up echoes
        try:
            await asyncio.wait_for(ws.recv(), 0.5)
        except TimeoutError:
            return ws


async def round_trips(ws: Any, name: str, size: int, count: int, in_flight: int) -> dict[str, float]:
    """Send ``count`` messages keeping ``in_flight`` outstanding; returns msgs/s, loss and RTTs."""
    pad = "x" * max(0, size - 24)
    sent_at: dict[int, float] = {}
    rtts: list[float] = []
    window = asyncio.Semaphore(in_flight)
    done = asyncio.Event()
    received = 0
    last_receipt = [0.0]

    async def reader() -> None:
        nonlocal received
        while received < count:
            frame = await ws.recv()
            # the client must not be the bottleneck: find the index without decoding JSON
            start_of_data = frame.index('"data"') + 6
            start_of_data = frame.index('"', start_of_data) + 1
            index = int(frame[start_of_data : frame.index(" ", start_of_data)])
            if index in sent_at:
                last_receipt[0] = time.perf_counter()
                rtts.append(last_receipt[0] - sent_at.pop(index))
                received += 1
                window.release()
        done.set()

    task = asyncio.create_task(reader())
    start = time.perf_counter()
    for index in range(count):
        try:
            await asyncio.wait_for(window.acquire(), 1.0)
        except TimeoutError:  # messages were lost: the window would never refill
            for _ in range(in_flight):
                window.release()
            await window.acquire()
        sent_at[index] = time.perf_counter()
        await ws.send(f'{{"op":"publish","topic":"/bench/{name}/in","msg":{{"data":"{index} {pad}"}}}}')
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(done.wait(), 3.0)
    elapsed = (last_receipt[0] if received else time.perf_counter()) - start
    task.cancel()
    return {
        "msgs_s": received / elapsed,
        "lost_pct": 100.0 * (count - received) / count,
        "p50_ms": 1000 * percentile(rtts, 0.5),
        "p95_ms": 1000 * percentile(rtts, 0.95),
        "p99_ms": 1000 * percentile(rtts, 0.99),
    }


async def service_calls(port: int, name: str, count: int, in_flight: int) -> dict[str, float]:
    ws = await connect(port)
    sent_at: dict[str, float] = {}
    rtts: list[float] = []
    failures = 0
    window = asyncio.Semaphore(in_flight)
    all_answered = asyncio.Event()

    async def reader() -> None:
        nonlocal failures
        answered = 0
        while answered < count:
            answer = json.loads(await ws.recv())
            if answer.get("op") != "service_response":
                continue
            rtts.append(time.perf_counter() - sent_at.pop(answer["id"]))
            failures += not answer.get("result")
            answered += 1
            window.release()
        all_answered.set()

    task = asyncio.create_task(reader())
    start = time.perf_counter()
    for index in range(count):
        await window.acquire()
        call_id = f"c{index}"
        sent_at[call_id] = time.perf_counter()
        await ws.send(
            json.dumps(
                {
                    "op": "call_service",
                    "id": call_id,
                    "service": f"/bench/{name}/echo_srv",
                    "type": "std_srvs/srv/SetBool",
                    "args": {"data": True},
                }
            )
        )
    await asyncio.wait_for(all_answered.wait(), 120)
    elapsed = time.perf_counter() - start
    task.cancel()
    await ws.close()
    return {
        "calls_s": count / elapsed,
        "failed": failures,
        "p50_ms": 1000 * percentile(rtts, 0.5),
        "p95_ms": 1000 * percentile(rtts, 0.95),
        "p99_ms": 1000 * percentile(rtts, 0.99),
    }


async def fan_out(port: int, name: str, clients: int, count: int) -> dict[str, float]:
    sockets = [await connect(port) for _ in range(clients)]
    for ws in sockets:
        await ws.send(
            json.dumps(
                {
                    "op": "subscribe",
                    "topic": f"/bench/{name}/fanout",
                    "type": "std_msgs/msg/String",
                    "queue_length": 1000,
                }
            )
        )
    latencies: list[float] = []
    received = [0] * clients

    async def reader(index: int, ws: Any) -> None:
        while True:
            data = json.loads(await ws.recv())["msg"]["data"]
            sequence, stamp = data.split(" ")
            latencies.append(time.time() - float(stamp))
            received[index] += 1
            if int(sequence) == count - 1:
                return

    readers = asyncio.gather(*(reader(i, ws) for i, ws in enumerate(sockets)))
    control = await connect(port)
    deadline = time.monotonic() + 30
    while True:  # the node starts only once the bridge's subscription has matched
        await control.send(
            json.dumps(
                {
                    "op": "call_service",
                    "id": "start",
                    "service": f"/bench/{name}/start_fanout",
                    "type": "std_srvs/srv/Trigger",
                    "args": {},
                }
            )
        )
        answer = json.loads(await asyncio.wait_for(control.recv(), 30))
        if answer.get("result") and answer["values"]["success"]:
            break
        if time.monotonic() > deadline:
            raise RuntimeError(f"fan-out never started: {answer}")
        await asyncio.sleep(0.1)  # poll the node until the bridge's subscription matched
    with contextlib.suppress(TimeoutError):
        await asyncio.wait_for(readers, count / FANOUT_HZ + 10)
    for ws in sockets + [control]:
        await ws.close()
    expected = clients * count
    return {"lost_pct": 100.0 * (expected - sum(received)) / expected, "p95_ms": 1000 * percentile(latencies, 0.95)}


async def measure(servers: dict[str, tuple[int, int]], quick: bool) -> list[Results]:
    """Each measurement runs on every server in turn, so load from elsewhere hits both alike.

    The echo measurements, about a second each, run in ROUNDS rounds, and which server goes
    first alternates from round to round (and from one measurement to the next): a figure is
    the median over the rounds (the mean for losses), so one noisy second decides nothing.
    """
    import psutil

    results = {name: Results(name) for name in servers}
    scale = 4 if quick else 1
    rounds = 2 if quick else ROUNDS
    sockets = {name: await echo_setup(port, name) for name, (port, _) in servers.items()}
    steps: list[tuple[str, int, Any]] = []
    for label, size in SIZES.items():
        count = (4000 if size <= 1024 else 1000) // scale
        steps.append(
            (
                f"echo {label}, {IN_FLIGHT} in flight",
                rounds,
                lambda name, port, size=size, count=count: round_trips(sockets[name], name, size, count, IN_FLIGHT),
            )
        )
    steps.append(
        ("rtt 64 B, 1 in flight", rounds, lambda name, port: round_trips(sockets[name], name, 64, 1000 // scale, 1))
    )
    steps.append(
        (f"services, {IN_FLIGHT} in flight", 1, lambda name, port: service_calls(port, name, 4000 // scale, IN_FLIGHT))
    )
    for clients in FANOUT_CLIENTS:
        steps.append(
            (
                f"fan-out {FANOUT_HZ} Hz to {clients}",
                1,
                lambda name, port, clients=clients: fan_out(port, name, clients, fanout_count(quick)),
            )
        )
    # Warm both paths through the echo node first (unrecorded): the first server measured
    # would otherwise meet a cold echo node alone.
    for name in servers:
        await round_trips(sockets[name], name, 64, WARM_UP, IN_FLIGHT)
    turn = 0
    for label, step_rounds, step in steps:
        runs: dict[str, list[dict[str, float]]] = {name: [] for name in servers}
        for _ in range(step_rounds):
            order = list(servers.items())
            for name, (port, _) in order[::-1] if turn % 2 else order:
                print(f"  {label}: {name}", file=sys.stderr, flush=True)
                runs[name].append(await step(name, port))
            turn += 1
        for name, figures in runs.items():
            results[name].figures[label] = {
                key: (statistics.mean if key.startswith("lost") else statistics.median)([f[key] for f in figures])
                for key in figures[0]
            }
    for name, (_, pid) in servers.items():
        results[name].figures["rss_mib"] = psutil.Process(pid).memory_info().rss / 2**20
        await sockets[name].close()
    return list(results.values())


async def soak(servers: dict[str, tuple[int, int]], seconds: float) -> list[Results]:
    """Echo traffic (64 B, 32 in flight, plus connecting and dropping clients) for ``seconds``
    on every server at once; RSS sampled every 10 s.  Reports first/last/peak RSS in MiB."""
    import psutil

    results = {name: Results(name) for name in servers}
    sockets = {name: await echo_setup(port, name) for name, (port, _) in servers.items()}
    samples: dict[str, list[float]] = {name: [] for name in servers}
    deadline = time.monotonic() + seconds
    next_sample = time.monotonic()
    while time.monotonic() < deadline:
        for name, (port, _pid) in servers.items():
            await round_trips(sockets[name], name, 64, 500, IN_FLIGHT)
            churn = await connect(port)
            await churn.send(
                json.dumps({"op": "subscribe", "topic": f"/bench/{name}/out", "type": "std_msgs/msg/String"})
            )
            await churn.close()
        if time.monotonic() >= next_sample:
            for name, (_, pid) in servers.items():
                samples[name].append(psutil.Process(pid).memory_info().rss / 2**20)
            next_sample += 10
    for name in servers:
        rss = samples[name]
        results[name].figures[f"soak {seconds:.0f} s: rss_mib"] = {"first": rss[0], "last": rss[-1], "peak": max(rss)}
        await sockets[name].close()
    return list(results.values())


def fanout_count(quick: bool) -> int:
    """Messages per fan-out burst (the echo node reads it from BENCH_FANOUT_COUNT)."""
    return 100 if quick else 300


def report(all_results: list[Results]) -> str:
    """A table of every figure; ratios of each Caretaker bridge to the Rust peer (the last
    column server), and of this checkout's bridge to the baseline when there is one."""
    names = [r.server for r in all_results]
    pairs = [(name, names[-1]) for name in names[:-1]] if len(names) > 1 else []
    if "baseline" in names and ("caretaker", "baseline") not in pairs:
        pairs.append(("caretaker", "baseline"))
    lines = [
        "| measurement | " + " | ".join(names) + "".join(f" | {a} ÷ {b}" for a, b in pairs) + " |",
        "|---" * (len(names) + 1 + len(pairs)) + "|",
    ]
    by_name = {r.server: r.figures for r in all_results}
    for key in all_results[0].figures:
        values = {name: by_name[name][key] for name in names}
        metrics = list(values[names[0]]) if isinstance(values[names[0]], dict) else [None]
        for metric in metrics:
            cell = {name: (v[metric] if metric is not None else v) for name, v in values.items()}
            ratios = "".join(f" | {cell[a] / cell[b]:.2f}" if cell[b] else " | " for a, b in pairs)
            label = f"{key}: {metric}" if metric is not None else key
            lines.append(
                f"| {label} | "
                + " | ".join(f"{cell[n]:.2f}" if isinstance(cell[n], float) else str(cell[n]) for n in names)
                + ratios
                + " |"
            )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--quick", action="store_true", help="a quarter of the messages")
    parser.add_argument("--only", choices=("caretaker", "rust"), help="measure one server only")
    parser.add_argument(
        "--soak",
        type=float,
        metavar="SECONDS",
        help="instead of the measurements: echo traffic for SECONDS, sampling RSS",
    )
    parser.add_argument(
        "--peer-dds-profile",
        action="store_true",
        help="run the Rust peer under the Fast DDS profile the bridge ships (docs/rosbridge.md)",
    )
    parser.add_argument(
        "--baseline",
        type=Path,
        metavar="DIR",
        help="also run the bridge whose python/ folder is in DIR (the code before a change)",
    )
    parser.add_argument("--echo-node", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.echo_node:
        return echo_node()
    names = [n for n in SERVERS if not args.only or args.only == n]
    if args.baseline:
        names.insert(1 if "caretaker" in names else 0, "baseline")
    env = dict(
        os.environ,
        ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST",
        BENCH_FANOUT_COUNT=str(fanout_count(args.quick)),
        BENCH_SERVERS=",".join(names),
    )
    env.setdefault("ROS_DOMAIN_ID", str(150 + os.getpid() % 50))
    os.environ.update(env)
    echo = subprocess.Popen([sys.executable, __file__, "--echo-node"], env=env, stdout=subprocess.PIPE, text=True)
    processes: list[subprocess.Popen] = [echo]
    try:
        wait_for_line(echo, r"^READY echo", 60)
        with tempfile.TemporaryDirectory() as workdir:
            servers: dict[str, tuple[int, int]] = {}
            for name in names:
                if name == "caretaker":
                    process, port = start_caretaker(env)
                elif name == "baseline":
                    process, port = start_caretaker(env, args.baseline)
                else:
                    process, port = start_rust(env, Path(workdir), args.peer_dds_profile)
                processes.append(process)
                servers[name] = (port, process.pid)
            if args.soak:
                all_results = asyncio.run(soak(servers, args.soak))
            else:
                all_results = asyncio.run(measure(servers, args.quick))
    finally:
        for process in reversed(processes):
            stop(process)
    print(report(all_results))
    return 0


if __name__ == "__main__":
    sys.exit(main())
