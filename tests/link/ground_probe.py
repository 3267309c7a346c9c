"""A ground-side rosbridge client (roslibpy) that a test drives from outside its namespace.

The test process lives in the root network namespace and cannot open sockets in the ground
one, so this process does the client's work there and takes requests over a Unix socket (the
file system crosses namespaces), one JSON object per line:

- ``{"op": "connect", "url": "ws://HOST:PORT", "timeout": S}`` opens the roslibpy client
- ``{"op": "echo", "data": TEXT, "timeout": S}`` publishes on /peer/echo_in until /peer/echo_out brings it back
- ``{"op": "call", "service": NAME, "type": TYPE, "args": {...}, "timeout": S}`` → ``values``
- ``{"op": "wait", "event": "close"|"ready", "count": N, "timeout": S}`` waits for the Nth such event
- ``{"op": "status"}`` → connection flag and event counts
- ``{"op": "tcp", "host": H, "port": P}`` → how a raw TCP connection there ends (``"reset"``, ``"closed"``,
  ``"answered"``, or the error), for checking a link that refuses connections

Every answer has ``ok`` and ``seconds`` (time spent on the request). Prints ``READY ground-probe PATH``.
"""

from __future__ import annotations

import contextlib
import json
import socket
import socketserver
import sys
import threading
import time
from collections import Counter
from typing import Any

import roslibpy


class Probe:
    """One roslibpy client and the counts of its connection events."""

    def __init__(self) -> None:
        self.ros: roslibpy.Ros | None = None
        self.events: Counter[str] = Counter()
        self.changed = threading.Condition()

    def _count(self, event: str) -> None:
        with self.changed:
            self.events[event] += 1
            self.changed.notify_all()

    def connect(self, url: str, timeout: float) -> dict[str, Any]:
        host, port = url.removeprefix("ws://").rsplit(":", 1)
        self.ros = roslibpy.Ros(host, int(port))
        self.ros.on("close", lambda *_: self._count("close"))
        self.ros.on("ready", lambda *_: self._count("ready"))  # every (re)connection
        self.ros.run(timeout=timeout)
        return {}

    def echo(self, data: str, timeout: float) -> dict[str, Any]:
        assert self.ros is not None
        received: list[str] = []
        arrived = threading.Event()

        def got(message: dict[str, Any]) -> None:
            if message.get("data") == data:
                received.append(message["data"])
                arrived.set()

        listener = roslibpy.Topic(self.ros, "/peer/echo_out", "std_msgs/String")
        listener.subscribe(got)
        talker = roslibpy.Topic(self.ros, "/peer/echo_in", "std_msgs/String")
        deadline = time.monotonic() + timeout
        try:
            while not arrived.is_set() and time.monotonic() < deadline:
                talker.publish(roslibpy.Message({"data": data}))  # until ROS matched the bridge's publisher
                arrived.wait(0.5)
        finally:
            listener.unsubscribe()
            talker.unadvertise()
        if not received:
            raise TimeoutError(f"{data!r} did not come back on /peer/echo_out within {timeout} s")
        return {"data": received[0]}

    def call(self, service: str, type_: str, args: dict[str, Any], timeout: float) -> dict[str, Any]:
        assert self.ros is not None
        response = roslibpy.Service(self.ros, service, type_).call(roslibpy.ServiceRequest(args), timeout=timeout)
        return {"values": dict(response)}

    def wait(self, event: str, count: int, timeout: float) -> dict[str, Any]:
        with self.changed:
            if not self.changed.wait_for(lambda: self.events[event] >= count, timeout):
                raise TimeoutError(f"{event} #{count} did not happen within {timeout} s (events: {dict(self.events)})")
        return {}

    def status(self) -> dict[str, Any]:
        with self.changed:
            return {"connected": bool(self.ros and self.ros.is_connected), "events": dict(self.events)}


def tcp(host: str, port: int) -> dict[str, Any]:
    """Open a raw connection, send an HTTP request line, and say how the connection ended."""
    try:
        with socket.create_connection((host, port), timeout=10) as sock:
            sock.sendall(b"GET / HTTP/1.1\r\nHost: probe\r\n\r\n")
            return {"ending": "answered" if sock.recv(100) else "closed"}
    except ConnectionResetError:
        return {"ending": "reset"}
    except OSError as exc:
        return {"ending": f"error: {exc}"}


class Handler(socketserver.StreamRequestHandler):
    """Answer each request line of one client."""

    probe: Probe

    def handle(self) -> None:
        for line in self.rfile:
            start = time.monotonic()
            try:
                request = json.loads(line)
                answer = {"ok": True, **self.dispatch(request)}
            except Exception as exc:
                answer = {"ok": False, "error": f"{type(exc).__name__}: {exc}"}
            answer["seconds"] = time.monotonic() - start
            self.wfile.write(json.dumps(answer).encode() + b"\n")
            self.wfile.flush()

    def dispatch(self, request: dict[str, Any]) -> dict[str, Any]:
        op, timeout = request["op"], float(request.get("timeout", 30))
        if op == "connect":
            return self.probe.connect(request["url"], timeout)
        if op == "echo":
            return self.probe.echo(request["data"], timeout)
        if op == "call":
            return self.probe.call(request["service"], request["type"], request.get("args", {}), timeout)
        if op == "wait":
            return self.probe.wait(request["event"], int(request["count"]), timeout)
        if op == "status":
            return self.probe.status()
        if op == "tcp":
            return tcp(request["host"], int(request["port"]))
        raise ValueError(f"unknown op {op!r}")


def main() -> None:
    path = sys.argv[1]
    Handler.probe = Probe()
    with socketserver.ThreadingUnixStreamServer(path, Handler) as server:
        server.daemon_threads = True
        print(f"READY ground-probe {path}", flush=True)
        with contextlib.suppress(KeyboardInterrupt):
            server.serve_forever()


if __name__ == "__main__":
    main()
