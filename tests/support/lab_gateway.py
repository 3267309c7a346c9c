"""A test bench system behind the PAX host shape, for executive tests and runner subprocesses.

Commands change its telemetry the way a real system would (``move`` sets ``state`` to the
target, ``vent`` opens the door). ``capture`` writes a real PNG file and returns its path.
Like the habitat's command ledger, it executes a command key at most once: a key sent again gets
the recorded result, or joins the execution still running (``resent`` lists such sends).
``lose_reply`` makes a command execute but answer UNKNOWN (a reply lost on the link); a blocked
command (``block``) waits until ``release`` or a cancel of its key (then it answers HALTED);
``set_link`` plays a link going down or up.
Tests steer it in-process through its attributes; a ``caretaker run`` subprocess selects it with
``PRIDE_GATEWAY=support.lab_gateway:open_lab`` (:data:`PRIDE_GATEWAY`, with :data:`IMPORT_ROOT`
on its ``PYTHONPATH``) and reads ``LAB_GATEWAY_BLOCK=<command>`` (that command never answers
unless cancelled, so a test can kill or interrupt the runner while it is in flight),
``LAB_GATEWAY_HOLD_REPLY=<command>`` (it executes, but its reply never comes back),
``LAB_GATEWAY_LEDGER=<file>`` (the ledger's record of keys and outcomes, kept across runner
processes as the habitat keeps it across ground restarts) and ``LAB_GATEWAY_IMAGES`` (where
captures go).
"""

from __future__ import annotations

import json
import os
import struct
import threading
import time
import zlib
from pathlib import Path
from typing import Any

from pride.systems import (
    CancelResult,
    CommandResult,
    LinkListener,
    LinkState,
    Outcome,
    TelemetryListener,
    TelemetryValue,
)

#: The ``PRIDE_GATEWAY`` value that makes a ``caretaker run`` subprocess open :func:`open_lab`.
PRIDE_GATEWAY = "support.lab_gateway:open_lab"
#: The tests folder: on a subprocess's ``PYTHONPATH``, it imports this module as ``support.lab_gateway``.
IMPORT_ROOT = Path(__file__).resolve().parents[1]

OK = Outcome.SUCCEEDED
LINK = "ws://lab.bench:9090"


class LabGateway:
    def __init__(self, image_dir: str | None = None, ledger_file: str | None = None) -> None:
        self.values: dict[str, Any] = {"temperature": 21.5, "door_open": False, "state": "idle", "docks": "dock, shelf"}
        self.stale: set[str] = set()
        self.sent: list[tuple[str, str, dict[str, Any]]] = []  # every execution (not re-sends of a known key)
        self.keys: list[str | None] = []  # the key of every send, re-sends included
        self.resent: list[str] = []  # keys sent again after they had executed
        self.fail_next: dict[str, str] = {}  # command -> message of its next (failing) answer
        self.failing: dict[str, str] = {}  # command -> message of every answer (it always fails)
        self.lose_reply: dict[str, str] = {}  # command -> why its next reply is lost (it executes; UNKNOWN)
        self.block: set[str] = set()
        self.hold_reply: set[str] = set()  # these execute, then their reply is lost for good
        self.release = threading.Event()  # unblocks in-process blocked commands
        self.cancels: list[str] = []
        self.cancel_seen = threading.Event()
        self.blocking = threading.Event()  # a blocked command is waiting now
        self.delay = 0.0  # the link's one-way delay
        self.robot_name = "lab"
        self.image_dir = Path(image_dir or os.environ.get("LAB_GATEWAY_IMAGES", "."))
        self._listeners: list[TelemetryListener] = []
        self._link_listeners: list[LinkListener] = []
        self._ledger_file = Path(ledger_file) if ledger_file else None
        self._ledger: dict[str, CommandResult] = {}
        if self._ledger_file is not None and self._ledger_file.exists():
            self._ledger = {
                key: CommandResult(Outcome(r["outcome"]), r["message"], r["values"])
                for key, r in json.loads(self._ledger_file.read_text()).items()
            }
        self._executing: dict[str, threading.Event] = {}  # keys being executed -> set when done
        self._running: dict[str, threading.Event] = {}  # blocked keys -> their cancel
        self._lock = threading.Lock()
        self.closed = False
        self.announce = False  # print a line per command, for a runner subprocess's output

    def system_ids(self) -> frozenset[str]:
        return frozenset({"lab"})

    def robot(self) -> str:
        return self.robot_name

    def one_way_delay(self) -> float:
        return self.delay

    def add_link_listener(self, callback: LinkListener) -> None:
        self._link_listeners.append(callback)

    def set_link(
        self, connected: bool, in_flight: int = 0, since: float | None = None, quiet_since: float | None = None
    ) -> None:
        """Tell the run the link went down (``since``), came back, or is up but quiet (``quiet_since``)."""
        state = LinkState(LINK, connected, None if connected else (since or time.time()), in_flight, quiet_since)
        for listener in list(self._link_listeners):
            listener(state)

    def cancel(self, key: str) -> CancelResult:
        with self._lock:
            self.cancels.append(key)
            running = self._running.get(key)
        self.cancel_seen.set()
        if running is None:
            return CancelResult(True, "nothing was moving")
        running.set()
        return CancelResult(True, "stopped where it was")

    def set(self, item: str, value: Any) -> None:
        with self._lock:
            self.values[item] = value
        for listener in list(self._listeners):
            listener("lab", item, TelemetryValue(value, time.time()))

    def execute(
        self, sysrep_id: str, command_id: str, args: dict[str, Any], *, key: str | None = None
    ) -> CommandResult:
        assert sysrep_id == "lab", sysrep_id
        done: threading.Event | None = None
        with self._lock:
            self.keys.append(key)
            known = key is not None and (key in self._ledger or key in self._executing)
            if known:
                self.resent.append(key)
                done = self._executing.get(key)
            else:
                self.sent.append((sysrep_id, command_id, dict(args)))
                if key is not None:
                    self._executing[key] = threading.Event()
        if known:
            if done is not None:
                done.wait()  # join the execution in progress
            return self._ledger[key]
        cancelled = threading.Event()
        with self._lock:
            self._running[key or command_id] = cancelled  # cancellable from before it is announced
        if self.announce:
            print(f"LAB executing {command_id}", flush=True)
        result = self._run(command_id, args, cancelled)
        with self._lock:
            self._running.pop(key or command_id, None)
        if key is not None:
            self._ledger[key] = result
            self._save_ledger()
            self._executing.pop(key).set()
        if command_id in self.hold_reply:
            print(f"LAB executed {command_id}, holding its reply", flush=True)
            threading.Event().wait()  # the reply never comes: the runner is killed meanwhile
        lost = self.lose_reply.pop(command_id, None)
        return CommandResult(Outcome.UNKNOWN, lost) if lost is not None else result

    def _save_ledger(self) -> None:
        if self._ledger_file is not None:
            records = {
                k: {"outcome": r.outcome.value, "message": r.message, "values": r.values}
                for k, r in self._ledger.items()
            }
            self._ledger_file.write_text(json.dumps(records))

    def _run(self, command_id: str, args: dict[str, Any], cancelled: threading.Event) -> CommandResult:
        if command_id in self.block:
            self.blocking.set()
            while not self.release.wait(0.02):  # a bench double: waits for either of two events
                if cancelled.is_set():
                    return CommandResult(Outcome.HALTED, f"{command_id} halted")
        if command_id in self.fail_next:
            return CommandResult(Outcome.FAILED, self.fail_next.pop(command_id), {})
        if command_id in self.failing:
            return CommandResult(Outcome.FAILED, self.failing[command_id], {})
        if command_id == "move":
            self.set("state", args["target"])
            return CommandResult(OK, f"moved to {args['target']}", {"arrived": True})
        if command_id == "vent":
            self.set("door_open", True)
            return CommandResult(OK, "vented", {})
        if command_id == "capture":
            self.image_dir.mkdir(parents=True, exist_ok=True)
            path = self.image_dir / f"{args['label']}.png"
            path.write_bytes(_png(4, 3))
            return CommandResult(OK, "captured", {"path": str(path), "label": args["label"]})
        return CommandResult(OK, "counted", {"total": args["n"] * 2})

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
    """Gateway factory for ``PRIDE_GATEWAY=support.lab_gateway:open_lab``."""
    gateway = LabGateway(ledger_file=os.environ.get("LAB_GATEWAY_LEDGER"))
    gateway.announce = True
    blocked = os.environ.get("LAB_GATEWAY_BLOCK")
    if blocked:
        gateway.block.add(blocked)
    held = os.environ.get("LAB_GATEWAY_HOLD_REPLY")
    if held:
        gateway.hold_reply.add(held)
    return gateway
