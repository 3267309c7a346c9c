"""Round trip of a SysRep command through the whole PAX chain vs the same call made with rclpy.

Chain: PaxHost.execute (Python) → JPype → Java ROS-convention plugin → rosbridge client →
WebSocket → `caretaker bridge` (rclpy) → ROS 2 service → back. Peer: an rclpy client in this
process calling the same service directly (cached client, as a well-written node would).
A third path sends the same rosbridge JSON from Python (websockets, sync client), so the
difference to the chain is what JPype and the Java plugin add on top of the rosbridge hop.
The service is a std_srvs/Trigger server in its own process (this file with --serve), so both
paths pay the same ROS 2 hop and only the chain's own overhead differs.

    .venv/bin/python bench/pax_chain.py [--calls 1000]
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import random
import statistics
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # imported where it runs: --serve and the direct rclpy client only
    from std_srvs.srv import Trigger

REPO = Path(__file__).resolve().parents[1]
NAMESPACE = "/bench_cdra"


class TriggerServer:
    """A Trigger service per command of sysrep/cdra.yaml, answering at once (process of --serve)."""

    def __init__(self) -> None:
        from rclpy.node import Node
        from std_srvs.srv import Trigger

        self.node = Node("pax_chain_bench_server")
        self.count = 0
        for command in ("unlock_filter", "lock_filter"):
            self.node.create_service(Trigger, f"{NAMESPACE}/{command}", self.trigger_callback)

    def trigger_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self.count += 1
        response.success = True
        response.message = f"call {self.count}"
        return response


def serve() -> int:
    import rclpy

    rclpy.init()
    server = TriggerServer()
    try:
        print("READY bench trigger server", flush=True)
        rclpy.spin(server.node)
    except KeyboardInterrupt:
        pass
    finally:
        server.node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


def percentiles(samples: list[float]) -> dict[str, float]:
    ordered = sorted(samples)
    return {
        "p50": ordered[len(ordered) // 2] * 1e3,
        "p95": ordered[int(len(ordered) * 0.95)] * 1e3,
        "mean": statistics.fmean(ordered) * 1e3,
    }


def time_calls(call, count: int) -> list[float]:  # noqa: ANN001
    samples = []
    for _ in range(count):
        start = time.perf_counter()
        call()
        samples.append(time.perf_counter() - start)
    return samples


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--calls", type=int, default=1000, help="measured calls per path (default 1000)")
    parser.add_argument("--warmup", type=int, default=200, help="unmeasured calls per path first (JIT, caches)")
    parser.add_argument("--serve", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    if args.serve:
        return serve()

    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    os.environ.setdefault("ROS_DOMAIN_ID", str(random.randint(101, 200)))
    from caretaker.processes import caretaker, python

    env = dict(os.environ)
    bridge = caretaker("bridge", "--port", "0", env=env)
    server = python(str(Path(__file__).resolve()), "--serve", env=env, name="trigger-server")
    host = None
    node = None
    resources = contextlib.ExitStack()
    try:
        bridge.wait_ready(60.0)
        server.wait_ready(60.0)
        url = next(line for line in bridge.output if line.startswith("READY bridge ")).split()[-1]

        import rclpy
        from rclpy.executors import SingleThreadedExecutor
        from std_srvs.srv import Trigger

        from pride.pax_host import PaxHost

        with tempfile.TemporaryDirectory() as tmp:
            binding = Path(tmp) / "bench.yaml"
            binding.write_text(
                f"robot: bench\nrosbridge: {url}\nsystems:\n- sysrep: {REPO / 'sysrep/cdra.yaml'}\n"
                f"  plugins: [ros_convention]\n  namespace: {NAMESPACE}\n"
            )
            host = PaxHost(binding)

        rclpy.init()
        node = rclpy.create_node("pax_chain_bench_client")
        client = node.create_client(Trigger, f"{NAMESPACE}/unlock_filter")
        executor = SingleThreadedExecutor()
        executor.add_node(node)
        threading.Thread(target=executor.spin, daemon=True).start()
        if not client.wait_for_service(timeout_sec=30.0):
            raise RuntimeError("the Trigger server did not appear")

        def direct() -> None:
            done = threading.Event()
            future = client.call_async(Trigger.Request())
            future.add_done_callback(lambda _: done.set())
            if not done.wait(10.0) or not future.result().success:
                raise RuntimeError("direct call failed")

        from websockets.sync.client import connect

        socket = resources.enter_context(connect(url))
        request = f'{{"op":"call_service","service":"{NAMESPACE}/unlock_filter","args":{{}},"id":"bench"}}'

        def raw_rosbridge() -> None:
            socket.send(request)
            if not json.loads(socket.recv(10.0))["values"]["success"]:
                raise RuntimeError("raw rosbridge call failed")

        def chain() -> None:
            if not host.execute("cdra", "unlock_filter", {}).success:
                raise RuntimeError("chain call failed")

        paths = {"direct rclpy": direct, "rosbridge JSON": raw_rosbridge, "PAX chain": chain}
        for call in paths.values():
            time_calls(call, args.warmup)
        # Interleave blocks so background load on the machine hits every path alike.
        results: dict[str, list[float]] = {name: [] for name in paths}
        block = max(1, args.calls // 10)
        while len(results["PAX chain"]) < args.calls:
            for name, call in paths.items():
                results[name] += time_calls(call, block)

        stats = {name: percentiles(samples[: args.calls]) for name, samples in results.items()}
        print(f"SysRep command cdra.unlock_filter, {args.calls} calls per path, one in flight")
        print(f"{'path':<16}{'p50 ms':>9}{'p95 ms':>9}{'mean ms':>9}")
        for name, s in stats.items():
            print(f"{name:<16}{s['p50']:>9.3f}{s['p95']:>9.3f}{s['mean']:>9.3f}")
        chain_s, direct_s, raw_s = stats["PAX chain"], stats["direct rclpy"], stats["rosbridge JSON"]
        print(
            f"chain overhead vs rclpy at p50: {chain_s['p50'] - direct_s['p50']:.3f} ms "
            f"(ratio {chain_s['p50'] / direct_s['p50']:.2f}x); at p95: {chain_s['p95'] - direct_s['p95']:.3f} ms"
        )
        print(
            f"of which JPype + Java plugin at p50: {chain_s['p50'] - raw_s['p50']:.3f} ms, "
            f"rosbridge hop: {raw_s['p50'] - direct_s['p50']:.3f} ms"
        )
    finally:
        resources.close()
        if host is not None:
            host.close()
        if node is not None:
            executor.shutdown()
            node.destroy_node()
        import rclpy

        if rclpy.ok():
            rclpy.shutdown()
        server.stop()
        bridge.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())
