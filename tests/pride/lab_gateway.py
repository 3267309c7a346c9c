"""A test bench system behind the PAX host shape, for executive tests and runner subprocesses.

Commands change its telemetry the way a real system would (``move`` sets ``state`` to the
target, ``vent`` opens the door). ``capture`` writes a real PNG file and returns its path.
Tests steer it in-process through its attributes; a ``caretaker run`` subprocess selects it with
``PRIDE_GATEWAY=lab_gateway:open_lab`` and reads ``LAB_GATEWAY_BLOCK=<command>`` (that command
never answers, so a test can kill the runner while it is in flight) and ``LAB_GATEWAY_IMAGES``
(where captures go).
"""

from __future__ import annotations

import os
import struct
import threading
import time
import zlib
from pathlib import Path
from typing import Any

from pride.systems import CommandResult, TelemetryListener, TelemetryValue


class LabGateway:
    def __init__(self, image_dir: str | None = None) -> None:
        self.values: dict[str, Any] = {"temperature": 21.5, "door_open": False, "state": "idle"}
        self.stale: set[str] = set()
        self.sent: list[tuple[str, str, dict[str, Any]]] = []
        self.fail_next: dict[str, str] = {}  # command -> message of its next (failing) answer
        self.block: set[str] = set()
        self.release = threading.Event()  # unblocks in-process blocked commands
        self.image_dir = Path(image_dir or os.environ.get("LAB_GATEWAY_IMAGES", "."))
        self._listeners: list[TelemetryListener] = []
        self._lock = threading.Lock()
        self.closed = False
        self.announce = False  # print a line per command, for a runner subprocess's output

    def system_ids(self) -> frozenset[str]:
        return frozenset({"lab"})

    def set(self, item: str, value: Any) -> None:
        with self._lock:
            self.values[item] = value
        for listener in list(self._listeners):
            listener("lab", item, TelemetryValue(value, time.time()))

    def execute(self, sysrep_id: str, command_id: str, args: dict[str, Any]) -> CommandResult:
        assert sysrep_id == "lab", sysrep_id
        with self._lock:
            self.sent.append((sysrep_id, command_id, dict(args)))
        if self.announce:
            print(f"LAB executing {command_id}", flush=True)
        if command_id in self.block:
            self.release.wait()
        if command_id in self.fail_next:
            return CommandResult(False, self.fail_next.pop(command_id), {})
        if command_id == "move":
            self.set("state", args["target"])
            return CommandResult(True, f"moved to {args['target']}", {"arrived": True})
        if command_id == "vent":
            self.set("door_open", True)
            return CommandResult(True, "vented", {})
        if command_id == "capture":
            self.image_dir.mkdir(parents=True, exist_ok=True)
            path = self.image_dir / f"{args['label']}.png"
            path.write_bytes(_png(4, 3))
            return CommandResult(True, "captured", {"path": str(path), "label": args["label"]})
        return CommandResult(True, "counted", {"total": args["n"] * 2})

    def telemetry(self, sysrep_id: str, item_id: str) -> TelemetryValue:
        with self._lock:
            return TelemetryValue(self.values[item_id], time.time(), item_id in self.stale)

    def add_listener(self, callback: TelemetryListener) -> None:
        self._listeners.append(callback)

    def close(self) -> None:
        self.closed = True


def _png(width: int, height: int) -> bytes:
    """A tiny grey PNG: enough to be a real image file a report can embed."""
    raw = b"".join(b"\x00" + b"\x80" * width for _ in range(height))

    def chunk(tag: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + tag + body + struct.pack(">I", zlib.crc32(tag + body))

    header = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def open_lab(binding_path: str) -> LabGateway:
    """Gateway factory for ``PRIDE_GATEWAY=lab_gateway:open_lab``."""
    gateway = LabGateway()
    gateway.announce = True
    blocked = os.environ.get("LAB_GATEWAY_BLOCK")
    if blocked:
        gateway.block.add(blocked)
    return gateway
