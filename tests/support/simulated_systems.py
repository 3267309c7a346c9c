"""Simulated systems behind the executive for the browser tests: the PAX host shape in-process.

The browser tests are about the web view, so the server under test opens this gateway instead
of the JVM-hosted PAX plugins (``PRIDE_GATEWAY=support.simulated_systems:open_simulated_systems``, see
pride/systems.py). It serves the SysReps the binding file names, with the state changes a
procedure checks: plans become valid, executions succeed, the CDRA latch locks and unlocks, the
camera writes a real PNG, perception finds objects where the drawings put them, the test bench's
plate (tests/web/fixtures/sysrep/bench.yaml) takes the temperature its heater is set to. The robot
side itself is tested by its own suites. ``SIMULATED_PACE`` (a recorded run's JSON,
support/recorded_run.py) makes each command take as long as the recorded robot side took for it:
the emulated habitats of support/emulated_habitat.py run at a real robot's pace.
"""

from __future__ import annotations

import os
import struct
import tempfile
import threading
import time
import zlib
from pathlib import Path
from typing import Any

import yaml

from pride.systems import CancelResult, CommandResult, LinkListener, Outcome, TelemetryListener, TelemetryValue
from procedure_language.sysrep import SysRep, load_sysrep
from support.recorded_run import command_durations, recorded_events

__all__ = ["SimulatedSystems", "open_simulated_systems"]


def _png(width: int, height: int, shade: int) -> bytes:
    """A small gradient PNG (no imaging library needed): what the camera 'captured'."""
    raw = b"".join(
        b"\x00" + b"".join(bytes(((x * 255) // width, (y * 255) // height, shade)) for x in range(width))
        for y in range(height)
    )

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", header) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


class SimulatedSystems:
    """Commands succeed and change the telemetry a real system would change."""

    def __init__(self, binding_path: str) -> None:
        binding = Path(binding_path)
        document = yaml.safe_load(binding.read_text(encoding="utf-8"))
        self._robot = str(document.get("robot", binding.stem))
        self._sysreps: dict[str, SysRep] = {}
        for system in document["systems"]:
            sysrep = load_sysrep(binding.parent / system["sysrep"])
            self._sysreps[sysrep.id] = sysrep
        self._lock = threading.Lock()  # guards _values, _listeners
        self._listeners: list[TelemetryListener] = []
        self._values: dict[tuple[str, str], Any] = {
            ("affordance_templates", "robot_active"): True,
            ("affordance_templates", "planner_node_active"): True,
            ("affordance_templates", "affordance_template_server_active"): True,
            ("affordance_templates", "execute_status"): "IDLE",
            ("affordance_templates", "plan_status"): "IDLE",
            ("affordance_templates", "plan_valid"): False,
            ("cdra", "filter_locked"): True,
            ("cdra", "filter_present"): True,
            ("cdra", "installed_filter_id"): "F-DIRTY-07",
            ("cdra", "installed_filter_condition"): "dirty",
            ("cdra", "clean_filter_ids"): "CDRA-F-0012, CDRA-F-0013",
            ("bench", "temperature"): 21.0,
        }
        #: a sensor that stopped reporting: its last value is served, marked stale
        self._stale = {("cdra", "installed_filter_condition")}
        # under the test's folder (SIMULATED_CAMERA_DIR): past runs' reports may still show them
        self._images = Path(tempfile.mkdtemp(prefix="camera-", dir=os.environ.get("SIMULATED_CAMERA_DIR")))
        self._captures = 0
        self._started = time.time()
        #: how long an execute_plan "moves the robot" (the web view's live camera captures meanwhile)
        self._motion_s = float(os.environ.get("SIMULATED_MOTION_S", "0"))
        pace = os.environ.get("SIMULATED_PACE")
        #: each command's recorded durations, by name: its n-th call takes the n-th (cycling)
        self._pace = command_durations(recorded_events(Path(pace))) if pace else {}
        self._calls: dict[str, int] = {}  # calls so far, by command name
        self._halt = threading.Event()  # set by a cancel: the motion in progress ends halted
        self._moving: str | None = None  # the key of the execute_plan in progress
        self._unanswered: set[str] = set()  # keys of captures whose first answer was lost
        self._instances: dict[str, int] = {}
        self._frames: dict[str, str] = {}

    def system_ids(self) -> frozenset[str]:
        return frozenset(self._sysreps)

    def robot(self) -> str:
        return self._robot

    def one_way_delay(self) -> float:
        return 0.0

    def cancel(self, key: str) -> CancelResult:
        with self._lock:
            moving = self._moving
        if moving is None:
            return CancelResult(True, "nothing was moving")
        self._halt.set()
        return CancelResult(True, f"motion {moving} stopped")

    def add_link_listener(self, callback: LinkListener) -> None:
        pass  # the simulated link never drops

    def _set(self, system: str, item: str, value: Any) -> None:
        with self._lock:
            self._values[(system, item)] = value
            listeners = list(self._listeners)
        for listener in listeners:
            listener(system, item, TelemetryValue(value, time.time()))

    def execute(
        self, sysrep_id: str, command_id: str, args: dict[str, Any], *, key: str | None = None
    ) -> CommandResult:
        sysrep = self._sysreps.get(sysrep_id)
        if sysrep is None or sysrep.command(command_id) is None:
            return CommandResult(Outcome.FAILED, f"{sysrep_id}.{command_id} is not served here")
        paced = self._paced(command_id)
        if command_id != "execute_plan":
            time.sleep(paced or 0.0)  # the robot side at work (a motion waits in _at, where a cancel halts it)
        if sysrep_id == "affordance_templates":
            return self._at(command_id, args, key or "", self._motion_s if paced is None else paced)
        if sysrep_id == "cdra":
            if command_id == "unlock_filter":
                self._set("cdra", "filter_locked", False)
            elif command_id == "lock_filter":
                self._set("cdra", "filter_locked", True)
            elif command_id in ("filter_in_slot", "slot_of_filter"):  # the cabinet's dirty one; a clean one in slot 1
                found = {"filter_id": args.get("filter_id") or "F-DIRTY-07", "slot": args.get("slot") or "rack/slot_1"}
                return CommandResult(Outcome.SUCCEEDED, "{filter_id} is seated in {slot}".format(**found), found)
            return CommandResult(Outcome.SUCCEEDED, f"{command_id} done")
        if sysrep_id == "bench" and command_id == "heat":
            self._set("bench", "temperature", float(args["celsius"]))
            return CommandResult(Outcome.SUCCEEDED, f"plate at {args['celsius']} degC")
        if sysrep_id == "camera":
            if args.get("label") == "unanswered" and key not in self._unanswered:  # the reply is lost once
                self._unanswered.add(str(key))
                return CommandResult(Outcome.UNKNOWN, "the reply never came: the image may have been taken")
            self._captures += 1
            path = self._images / f"{self._captures:03d}_{args.get('label') or 'capture'}.png"
            path.write_bytes(_png(160, 120, (self._captures * 70) % 256))
            return CommandResult(Outcome.SUCCEEDED, "captured", {"path": str(path)})
        if sysrep_id == "perception" and command_id == "locate":  # a world where the drawings put it
            pose = dict.fromkeys(("x", "y", "z", "roll", "pitch", "yaw", "qx", "qy", "qz"), 0.0)
            located = {**pose, "qw": 1.0, "residual_px": 0.2, "markers": "30,31", "distance": 1.0}
            return CommandResult(
                Outcome.SUCCEEDED,
                f"located {args.get('object')}",
                {**located, "offset_mm": 0.0, "offset_deg": 0.0, "frame": str(args.get("frame") or "world")},
            )
        return CommandResult(Outcome.SUCCEEDED, "ok")

    def _paced(self, command_id: str) -> float | None:
        """How long this call of ``command_id`` takes at the recorded pace (None: not paced)."""
        durations = self._pace.get(command_id)
        if not durations:
            return None
        with self._lock:
            calls = self._calls[command_id] = self._calls.get(command_id, 0) + 1
        return durations[(calls - 1) % len(durations)]

    def _at(self, command_id: str, args: dict[str, Any], key: str, seconds: float) -> CommandResult:
        """An AT command; ``seconds``: how long an execute_plan moves (unless halted)."""
        template = str(args.get("affordance_template", "")).split(":")[0]
        if command_id == "add_affordance_template":
            self._instances[template] = len(self._instances)
            return CommandResult(
                Outcome.SUCCEEDED,
                f"added {template}",
                {"id": self._instances[template], "instance": f"{template}:{self._instances[template]}"},
            )
        if template not in self._instances:
            return CommandResult(Outcome.FAILED, f"no instance of {template!r}: add the template first")
        if command_id == "set_display_object_pose":
            self._frames[template] = str(args.get("frame", ""))
            return CommandResult(Outcome.SUCCEEDED, f"{template} moved to {self._frames[template]}")
        if command_id == "plan_trajectory":
            self._set("affordance_templates", "plan_status", "PLANNED")
            self._set("affordance_templates", "plan_valid", True)
            return CommandResult(
                Outcome.SUCCEEDED,
                "planned",
                {"plan_status": "PLANNED", "plan_valid": True, "end_pose": [0.62, -0.18, 0.95, 0.0, 1.57, 0.35]},
            )
        if command_id == "execute_plan":
            self._set("affordance_templates", "execute_status", "EXECUTING")
            with self._lock:
                self._moving = key
                self._halt.clear()
            # a long reach moves until halted (for the halt tests); others move ``seconds``
            halted = self._halt.wait(600.0 if args.get("trajectory") == "long_reach" else seconds)
            with self._lock:
                self._moving = None
            if halted:
                self._set("affordance_templates", "execute_status", "HALTED")
                return CommandResult(Outcome.HALTED, "the motion stopped on a cancel")
            at_cabinet = self._frames.get(template) == "cabinet/slot"
            if at_cabinet and args.get("trajectory") == "grasp_and_pull":
                self._set("cdra", "filter_present", False)
            elif at_cabinet and args.get("trajectory") == "insert_and_release":
                self._set("cdra", "filter_present", True)
            self._set("affordance_templates", "execute_status", "SUCCEEDED")
            self._set("affordance_templates", "plan_valid", False)
            return CommandResult(Outcome.SUCCEEDED, "executed", {"execute_status": "SUCCEEDED"})
        if command_id == "delete_affordance_template":
            del self._instances[template]
        return CommandResult(Outcome.SUCCEEDED, f"{command_id} done")

    def telemetry(self, sysrep_id: str, item_id: str) -> TelemetryValue:
        with self._lock:
            if (sysrep_id, item_id) not in self._values:
                raise KeyError(f"{sysrep_id}.{item_id} is not served here")
            if (sysrep_id, item_id) in self._stale:
                return TelemetryValue(self._values[(sysrep_id, item_id)], self._started - 60.0, True)
            return TelemetryValue(self._values[(sysrep_id, item_id)], time.time(), False)

    def add_listener(self, callback: TelemetryListener) -> None:
        with self._lock:
            self._listeners.append(callback)

    def close(self) -> None:
        with self._lock:
            self._listeners.clear()


def open_simulated_systems(binding_path: str) -> SimulatedSystems:
    """The factory named by PRIDE_GATEWAY in the browser tests."""
    return SimulatedSystems(binding_path)
