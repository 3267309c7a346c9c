"""The paper's demonstrations, end to end: stack up, procedure in autonomous mode, report.

The procedure runs in its own process (``caretaker run``, with its own JVM), exactly as an
operator would start it. The demo then checks the *world*, not the procedure's word for it:
a run that says COMPLETED while the filter is still in the wrong place is a failed demo.
"""

from __future__ import annotations

import argparse
import math
import threading
import time
from pathlib import Path
from urllib.parse import urlparse

import yaml

from caretaker.processes import REPO, ProcessFailed, caretaker
from caretaker.stack import Scenario, Stack, StackFailed

__all__ = ["EndStateError", "iva_end_state", "eva_end_state", "run_demo"]

DEFAULT_DB = f"sqlite:///{REPO / 'var' / 'caretaker.db'}"
#: Operator answers for the unattended demo runs (what the operator would type at the prompts).
DEMO_INPUTS: dict[str, dict[str, str]] = {
    "iva": {"clean_filter_id": "CDRA-F-0012"},
    "eva": {"damage": "false"},
}
#: How far a filter may sit from its slot frame and still count as seated (m).
SEATED_TOLERANCE = 0.03


class EndStateError(RuntimeError):
    """The world is not in the state the procedure was meant to leave it in."""


def _topic_value(ros: object, name: str, msg_type: str, timeout: float) -> dict:
    """First message on ``name`` via rosbridge (latched topics answer at once)."""
    import roslibpy

    received: dict = {}
    arrived = threading.Event()

    def take(message: dict) -> None:
        received.update(message)
        arrived.set()

    topic = roslibpy.Topic(ros, name, msg_type)
    topic.subscribe(take)
    try:
        if not arrived.wait(timeout):
            raise EndStateError(f"no message on {name} within {timeout} s")
        return received
    finally:
        topic.unsubscribe()


def iva_end_state(bridge_url: str, scene_file: Path, clean_filter_id: str, timeout: float = 20.0) -> list[str]:
    """Check the IVA world after the CDRA procedure; return what was verified.

    Raises:
        EndStateError: the clean filter is not locked in the cabinet, or the dirty filter is not
            seated in the slot that was empty at the start.
    """
    import roslibpy

    scene = yaml.safe_load(scene_file.read_text())
    dirty = next(f for f in scene["filters"] if f["condition"] == "dirty")
    occupied = {f["slot"] for f in scene["filters"]}
    empty_slot = next(s["name"] for s in scene["slots"] if s["name"] not in occupied)
    url = urlparse(bridge_url)
    ros = roslibpy.Ros(host=url.hostname, port=url.port)
    ros.run(timeout)
    try:
        installed = _topic_value(ros, "/cdra/installed_filter_id", "std_msgs/String", timeout)["data"]
        locked = _topic_value(ros, "/cdra/filter_locked", "std_msgs/Bool", timeout)["data"]
        frames = _topic_value(ros, "/sim/frames", "caretaker_sim_msgs/NamedPoses", timeout)
    finally:
        ros.close()
    poses = dict(zip(frames["names"], frames["poses"]))
    if installed != clean_filter_id:
        raise EndStateError(f"cabinet holds {installed or 'nothing'!r}, expected the clean filter {clean_filter_id!r}")
    if not locked:
        raise EndStateError(f"{clean_filter_id} is in the cabinet but not locked")
    dirty_pose, slot_pose = poses.get(f"filter/{dirty['id']}"), poses.get(empty_slot)
    if dirty_pose is None or slot_pose is None:
        raise EndStateError(f"frames filter/{dirty['id']} or {empty_slot} are not published")
    distance = math.dist(*(tuple(p["position"][k] for k in "xyz") for p in (dirty_pose, slot_pose)))
    if distance > SEATED_TOLERANCE:
        raise EndStateError(f"dirty filter {dirty['id']} is {distance:.3f} m from {empty_slot}, not seated there")
    return [
        f"cabinet holds {installed}, locked",
        f"dirty filter {dirty['id']} seated in {empty_slot} ({distance * 1000:.0f} mm from the slot frame)",
    ]


def eva_end_state(db_url: str, run_id: str, scene_file: Path) -> list[str]:
    """Check that the EVA run captured a non-empty image of every hull target in the scene.

    Raises:
        EndStateError: a target has no captured image, or an image file is missing or empty.
    """
    from pride.audit_log import AuditLog
    from pride.events import EventKind

    targets = [t["name"] for t in yaml.safe_load(scene_file.read_text())["targets"]]
    audit = AuditLog(db_url)
    try:
        events = audit.events(run_id)
    finally:
        audit.close()
    images: dict[str, Path] = {}
    for event in events:
        if event.kind is EventKind.COMMAND_RESULT and event.data.get("success"):
            path = (event.data.get("values") or {}).get("path")
            label = (event.data.get("args") or {}).get("label")
            if path and label:
                images[label] = Path(path)
    missing = [t for t in targets if t not in images]
    if missing:
        raise EndStateError(f"no image captured of {', '.join(missing)}")
    empty = [t for t in targets if not images[t].is_file() or images[t].stat().st_size == 0]
    if empty:
        raise EndStateError(f"image files missing or empty for {', '.join(empty)}")
    return [f"{target}: {images[target]}" for target in targets]


def _run_procedure(scenario: Scenario, db_url: str, env: dict[str, str], started: float) -> tuple[str | None, str]:
    """Run the scenario's procedure autonomously in its own process; return (run id, final status)."""
    answers = [f"--set={name}={value}" for name, value in DEMO_INPUTS[scenario.scene].items()]
    result: dict[str, str] = {}

    def show(_: str, line: str) -> None:
        print(f"[{time.monotonic() - started:7.1f} s] {line}", flush=True)
        words = line.split()
        if line.startswith("READY run") and len(words) >= 3:
            result["run"] = words[2]
        elif line.startswith("RESULT") and len(words) >= 4:
            result["status"], result["run"] = words[1], words[3]

    runner = caretaker(
        "run", str(scenario.procedure), "--binding", str(scenario.binding), "--auto", "--user", "demo",
        "--db", db_url, "--confirm-manual", *answers, env=env, name="run", on_line=show,
    )
    runner.proc.wait()
    runner.stop()
    return result.get("run"), result.get("status", f"runner exited with {runner.proc.returncode}")


def _serve(db_url: str, env: dict[str, str]) -> None:
    """Leave the web view running on the demo's audit log until Ctrl-C."""
    web = caretaker("serve", "--db", db_url, env=env, name="serve")
    try:
        print(web.wait_ready(60), "— Ctrl-C to stop", flush=True)
        web.proc.wait()
    except KeyboardInterrupt:
        pass
    except ProcessFailed as exc:
        print(f"caretaker demo: the web view did not start: {exc}")
    finally:
        web.stop()


def run_demo(scenario: Scenario, args: argparse.Namespace) -> int:
    """Bring the stack up, run the procedure, check the world, write the report. Exit 0 only if all hold."""
    binding = yaml.safe_load(scenario.binding.read_text())
    bridge_url = binding["rosbridge"]
    port = urlparse(bridge_url).port or 9090
    db_url = args.db or DEFAULT_DB
    (REPO / "var").mkdir(exist_ok=True)
    started = time.monotonic()
    stack = Stack(scenario, time_scale=args.time_scale, bridge_address=args.bridge_address, bridge_port=port, echo=args.verbose)
    print(f"Starting the {scenario.scene.upper()} stack: simulation, planner, AT server, rosbridge ({bridge_url})", flush=True)
    try:
        stack.start()
    except StackFailed as exc:
        print(f"caretaker demo: {exc}")
        return 1
    try:
        print(f"[{time.monotonic() - started:7.1f} s] stack ready; running {scenario.procedure.name} autonomously", flush=True)
        run_id, status = _run_procedure(scenario, db_url, stack.env, started)
        dead = stack.dead_parts()
        if dead:
            print(f"caretaker demo: {', '.join(dead)} died during the run")
            return 1
        if status != "completed" or run_id is None:
            print(f"caretaker demo: the procedure did not complete ({status})")
            return 1
        scene_file = REPO / "sim" / "scenes" / f"{scenario.scene}.yaml"
        try:
            if scenario.scene == "iva":
                verified = iva_end_state(bridge_url, scene_file, DEMO_INPUTS["iva"]["clean_filter_id"])
            else:
                verified = eva_end_state(db_url, run_id, scene_file)
        except EndStateError as exc:
            print(f"caretaker demo: the procedure completed but the world is wrong: {exc}")
            return 1
        for line in verified:
            print(f"  verified: {line}")
        report = caretaker("report", run_id, "--db", db_url, "--out", str(REPO / "var" / "reports"), env=stack.env, name="report")
        report.proc.wait()
        report.stop()
        if report.proc.returncode != 0:
            print(f"caretaker demo: the report failed:\n{report.tail()}")
            return 1
        print(f"[{time.monotonic() - started:7.1f} s] {scenario.scene.upper()} demo complete; run {run_id}")
        print(f"  audit log: {db_url}")
        for line in report.output:
            print(f"  report: {line}")
        if args.serve:
            _serve(db_url, stack.env)
        return 0
    finally:
        stack.stop()
