"""The habitat-side service the ledger tests command, run as its own process: it counts every
execution it receives, so a test can check that a key ran exactly once.

Offers (std_srvs): ``/ledger_test/count`` (Trigger, answers at once), ``/ledger_test/refuse``
(Trigger, answers ``success: false``), ``/ledger_test/hold`` (Trigger, answers once
``/ledger_test/release`` is called), ``/ledger_test/set`` (SetBool, echoes data), and
``/ledger_test/counts`` (Trigger, not counted: the counts as JSON in ``message``). Prints
``CALLED <name> <n>`` for each execution and ``READY ledger-peer`` once it serves.
"""

from __future__ import annotations

import json
import sys
import threading
from collections import Counter

import rclpy
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from std_srvs.srv import SetBool, Trigger

HOLD_LIMIT_S = 120.0


class LedgerPeer(Node):
    def __init__(self) -> None:
        super().__init__("ledger_test_peer")
        group = ReentrantCallbackGroup()
        deep = QoSProfile(depth=1000)
        self.counts: Counter[str] = Counter()
        self.counts_lock = threading.Lock()
        self.released = threading.Condition()
        self.releases = 0
        for name, kind, callback in (
            ("count", Trigger, self.count_callback),
            ("refuse", Trigger, self.refuse_callback),
            ("hold", Trigger, self.hold_callback),
            ("release", Trigger, self.release_callback),
            ("set", SetBool, self.set_callback),
            ("counts", Trigger, self.counts_callback),
        ):
            self.create_service(kind, f"/ledger_test/{name}", callback, qos_profile=deep, callback_group=group)

    def _executed(self, name: str) -> int:
        with self.counts_lock:
            self.counts[name] += 1
            number = self.counts[name]
        print(f"CALLED {name} {number}", flush=True)
        return number

    def count_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        response.success, response.message = True, f"count {self._executed('count')}"
        return response

    def refuse_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        self._executed("refuse")
        response.success, response.message = False, "refused by the peer"
        return response

    def hold_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        number = self._executed("hold")
        with self.released:
            seen = self.releases
            released = self.released.wait_for(lambda: self.releases > seen, HOLD_LIMIT_S)
        response.success, response.message = released, f"held {number}" if released else "never released"
        return response

    def release_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self.released:
            self.releases += 1
            self.released.notify_all()
        response.success = True
        return response

    def set_callback(self, request: SetBool.Request, response: SetBool.Response) -> SetBool.Response:
        self._executed("set")
        response.success, response.message = True, f"set {str(request.data).lower()}"
        return response

    def counts_callback(self, request: Trigger.Request, response: Trigger.Response) -> Trigger.Response:
        with self.counts_lock:
            response.success, response.message = True, json.dumps(dict(self.counts))
        return response


def main() -> int:
    rclpy.init()
    node = LedgerPeer()
    executor = MultiThreadedExecutor(num_threads=8)
    executor.add_node(node)
    try:
        print("READY ledger-peer", flush=True)
        executor.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        executor.shutdown()
        node.destroy_node()
        if rclpy.ok():
            rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
