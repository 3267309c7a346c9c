"""Drives roslibpy (PyPI) through the ``clients`` cases of ``caretaker interop --serve``.

``python -m interop.clients.roslibpy_driver ws://127.0.0.1:PORT``: one roslibpy ``Ros`` per case
on the case's path, used as a program would use it, and one more on ``/report`` that tells the
server what the program received. The waits below are the driver's patience with the client
(how long a program would wait before calling it a failure), never a synchronisation with the
server: the server's answers to the reports say when a step has been played.
"""

from __future__ import annotations

import json
import logging
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import roslibpy

REPORT_TIMEOUT = 30.0  # the report of the drop case is answered once the server played the reconnection
PATIENCE = 3.0


class Driver:
    def __init__(self, url: str) -> None:
        self.url = url.rstrip("/")
        self.reporter = roslibpy.Ros(f"{self.url}/report")
        self.reporter.run(timeout=10)
        self.report_service = roslibpy.Service(self.reporter, "/interop/report", "interop/Report")

    def report(self, case: str, observed: dict[str, Any]) -> dict[str, Any]:
        print(f"{case}: {json.dumps(observed)[:200]}", flush=True)
        request = roslibpy.ServiceRequest({"case": case, "observed": json.dumps(observed)})
        values: dict[str, Any] = dict(self.report_service.call(request, timeout=REPORT_TIMEOUT))
        return values

    def open(self, case: str, before_run: Callable[[Any], None] | None = None) -> Any:
        ros = roslibpy.Ros(f"{self.url}/{case}")
        if before_run is not None:
            before_run(ros)
        ros.run(timeout=10)
        return ros

    def out_of_order(self) -> None:
        ros = self.open("clients.1")
        echo = roslibpy.Service(ros, "/interop/echo", "interop/Echo")
        got: dict[str, Any] = {}
        both = threading.Event()

        def keep(name: str) -> Callable[[Any], None]:
            def store(values: Any) -> None:
                got[name] = values.get("data") if isinstance(values, dict) or hasattr(values, "get") else values
                if len(got) == 2:
                    both.set()

            return store

        for name in ("first", "second"):
            echo.call(roslibpy.ServiceRequest({"data": name}), keep(name), keep(name))
        both.wait(PATIENCE * 2)
        self.report("clients.1", {**got, "done": True})
        ros.close()

    def messages(self, case: str, topic: str) -> None:
        """Subscribe to ``topic`` and report what arrives until ``after`` (or the driver's patience)."""
        ros = self.open(case)
        observed: dict[str, Any] = {"received": [], "status": None}
        after = threading.Event()

        def receive(message: Any) -> None:
            observed["received"].append(message.get("data"))
            if message.get("data") == "after":
                after.set()

        roslibpy.Topic(ros, topic, "std_msgs/msg/String").subscribe(receive)
        after.wait(PATIENCE)
        self.report(case, {**observed, "done": True})
        ros.close()

    def dropped(self) -> None:
        ros = self.open("clients.4")
        received: list[Any] = []
        arrived = threading.Event()

        def receive(message: Any) -> None:
            received.append(message.get("data"))
            if message.get("data") == "after-reconnect":
                arrived.set()

        def serve(request: Any, response: Any) -> bool:
            response["served"] = True
            return True

        roslibpy.Topic(ros, "/interop/drop", "std_msgs/msg/String").subscribe(receive)
        roslibpy.Topic(ros, "/interop/drop_pub", "std_msgs/msg/String").advertise()
        roslibpy.Service(ros, "/interop/drop_service", "std_srvs/srv/Trigger").advertise(serve)
        registered = [
            "subscribe /interop/drop",
            "advertise /interop/drop_pub",
            "advertise_service /interop/drop_service",
        ]
        answer = self.report("clients.4", {"registered": registered})
        if answer.get("reconnected"):
            arrived.wait(PATIENCE)
        self.report("clients.4", {"received": received, "done": True})
        ros.close()

    def slow(self) -> None:
        ros = self.open("clients.5")
        try:
            roslibpy.Service(ros, "/interop/slow", "interop/Echo").call(roslibpy.ServiceRequest({}), timeout=0.5)
            outcome = "answered"
        except Exception as exc:  # roslibpy's timeout is a plain Exception naming it
            outcome = "timed out" if "time" in f"{type(exc).__name__} {exc}".lower() else f"error: {exc}"
        self.report("clients.5", {"timeout_offered": True, "slow_call": outcome})
        try:
            values = roslibpy.Service(ros, "/interop/echo", "interop/Echo").call(
                roslibpy.ServiceRequest({"data": "after-late"}), timeout=PATIENCE
            )
            after = values.get("data")
        except Exception as exc:  # reported as what the program saw
            after = f"error: {exc}"
        self.report("clients.5", {"after_late": after, "done": True})
        ros.close()

    def refused_auth(self) -> None:
        closed = threading.Event()

        def login(ros: Any) -> None:
            now = time.time()
            ros.on("close", lambda *_: closed.set())
            ros.authenticate("0" * 64, "interop", f"{self.url}/clients.6", "0123456789abcdef", now, "user", now + 60)

        ros = self.open("clients.6", login)
        closed.wait(PATIENCE)
        # roslibpy hands the program no status and no close reason: only the close event
        self.report(
            "clients.6",
            {
                "auth_offered": True,
                "refusal": None,
                "closed": closed.is_set(),
                "connected": ros.is_connected,
                "done": True,
            },
        )
        ros.close()

    def run(self) -> None:
        self.report("hello", {"client": f"roslibpy {roslibpy.__version__}"})
        self.out_of_order()
        self.messages("clients.2", "/interop/fragmented")
        self.messages("clients.3", "/interop/status_after")
        self.dropped()
        self.slow()
        self.refused_auth()
        self.report("bye", {})


def main(argv: list[str]) -> int:
    if len(argv) != 1 or not argv[0].startswith(("ws://", "wss://")):
        print("usage: python -m interop.clients.roslibpy_driver ws://HOST:PORT", file=sys.stderr)
        return 2
    logging.basicConfig(level=logging.ERROR)
    driver = Driver(argv[0])
    try:
        driver.run()
    finally:
        driver.reporter.terminate()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
