"""``caretaker demo DEPLOYMENT``: stack up, the deployment's procedure autonomously, world check, report.

The procedure runs in its own process (``caretaker run``, with its own JVM), exactly as an
operator would start it, with the answers the deployment's ``demo.inputs`` give. The demo then
checks the *world*, not the procedure's word for it — the check the deployment names in
``demo.check`` (:data:`WORLD_CHECKS`): a run that says COMPLETED while the filter is still in the
wrong place is a failed demo.
"""

from __future__ import annotations

import argparse
import logging
import math
import secrets
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any
from urllib.parse import urlparse

from caretaker.deployment import DemoRun, Deployment, load_deployment
from caretaker.processes import REPO, ProcessFailed, caretaker
from caretaker.stack import Stack, StackFailed, stack_options
from console.accounts import AccountStore
from datafile import DataFileError
from sim.scene import load_scene

__all__ = [
    "DEMO_USER",
    "EndStateError",
    "WORLD_CHECKS",
    "demo_main",
    "demo_operator",
    "eva_end_state",
    "iva_end_state",
    "run_demo",
]

DEFAULT_DB = f"sqlite:///{REPO / 'var' / 'caretaker.db'}"
#: The operator account ``--serve`` signs in with (an account of the demo's database like any other).
DEMO_USER = "demo"
#: How far a filter may sit from its slot frame and still count as seated (m).
SEATED_TOLERANCE = 0.03


class EndStateError(RuntimeError):
    """The world is not in the state the procedure was meant to leave it in."""


def _topic_value(ros: object, name: str, msg_type: str, timeout: float) -> dict[str, Any]:
    """First message on ``name`` via rosbridge (latched topics answer at once)."""
    import roslibpy

    received: dict[str, Any] = {}
    arrived = threading.Event()

    def take(message: dict[str, Any]) -> None:
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

    scene = load_scene(scene_file)
    dirty = next((f for f in scene.filters if f.condition == "dirty"), None)
    occupied = {f.slot for f in scene.filters}
    empty_slot = next((name for name in scene.slots if name not in occupied), None)
    if dirty is None or empty_slot is None:
        raise EndStateError(f"scene {scene_file} has no dirty filter or no empty slot: this check does not apply to it")
    url = urlparse(bridge_url)
    ros = roslibpy.Ros(host=url.hostname, port=url.port)
    ros.run(timeout)
    try:
        installed = _topic_value(ros, "/cdra/installed_filter_id", "std_msgs/String", timeout)["data"]
        locked = _topic_value(ros, "/cdra/filter_locked", "std_msgs/Bool", timeout)["data"]
        frames = _topic_value(ros, "/sim/frames", "caretaker_sim_msgs/NamedPoses", timeout)
    finally:
        ros.close()
    poses = dict(zip(frames["names"], frames["poses"], strict=False))
    if installed != clean_filter_id:
        raise EndStateError(f"cabinet holds {installed or 'nothing'!r}, expected the clean filter {clean_filter_id!r}")
    if not locked:
        raise EndStateError(f"{clean_filter_id} is in the cabinet but not locked")
    dirty_pose, slot_pose = poses.get(f"filter/{dirty.id}"), poses.get(empty_slot)
    if dirty_pose is None or slot_pose is None:
        raise EndStateError(f"frames filter/{dirty.id} or {empty_slot} are not published")
    distance = math.dist(*(tuple(p["position"][k] for k in "xyz") for p in (dirty_pose, slot_pose)))
    if distance > SEATED_TOLERANCE:
        raise EndStateError(f"dirty filter {dirty.id} is {distance:.3f} m from {empty_slot}, not seated there")
    return [
        f"cabinet holds {installed}, locked",
        f"dirty filter {dirty.id} seated in {empty_slot} ({distance * 1000:.0f} mm from the slot frame)",
    ]


def eva_end_state(db_url: str, run_id: str, scene_file: Path) -> list[str]:
    """Check that the EVA run captured a non-empty image of every hull target in the scene.

    Raises:
        EndStateError: a target has no captured image, or an image file is missing or empty.
    """
    from pride.audit_log import AuditLog
    from pride.events import EventKind

    targets = [t.name for t in load_scene(scene_file).targets]
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


#: The world checks a deployment's ``demo.check`` may name: what each verifies after the run.
WORLD_CHECKS: dict[str, Callable[[Deployment, str, str, str], list[str]]] = {
    "cdra_filters_swapped": lambda d, bridge_url, db_url, run_id: iva_end_state(
        bridge_url, d.scene, (d.demo.inputs if d.demo else {}).get("clean_filter_id", "")
    ),
    "every_target_imaged": lambda d, bridge_url, db_url, run_id: eva_end_state(db_url, run_id, d.scene),
}


def _run_procedure(
    demo: DemoRun, bridge_url: str, db_url: str, env: dict[str, str], started: float
) -> tuple[str | None, str]:
    """Run the demo's procedure autonomously in its own process; return (run id, final status)."""
    answers = [f"--set={name}={value}" for name, value in demo.inputs.items()]
    result: dict[str, str] = {}

    def show(_: str, line: str) -> None:
        print(f"[{time.monotonic() - started:7.1f} s] {line}", flush=True)
        words = line.split()
        if line.startswith("READY run") and len(words) >= 3:
            result["run"] = words[2]
        elif line.startswith("RESULT") and len(words) >= 4:
            result["status"], result["run"] = words[1], words[3]

    runner = caretaker(
        "run",
        str(demo.procedure),
        "--binding",
        str(demo.binding),
        "--rosbridge",
        bridge_url,
        "--auto",
        "--user",
        "demo",
        "--db",
        db_url,
        "--confirm-manual",
        *answers,
        env=env,
        name="run",
        on_line=show,
    )
    runner.proc.wait()
    runner.stop()
    return result.get("run"), result.get("status", f"runner exited with {runner.proc.returncode}")


def demo_operator(db_url: str) -> str:
    """Give the demo operator account (:data:`DEMO_USER`) a new random password, creating the account
    if needed; returns the password, which is shown once and stored only as its hash."""
    password = secrets.token_urlsafe(12)
    store = AccountStore(db_url)
    try:
        if store.get(DEMO_USER) is None:
            store.add(DEMO_USER, "operator", password, name="Demo operator")
        else:
            store.set_password(DEMO_USER, password)
    finally:
        store.close()
    return password


def _serve(db_url: str, env: dict[str, str]) -> None:
    """Leave the web view running on the demo's audit log until Ctrl-C, with an operator who can sign in."""
    password = demo_operator(db_url)
    web = caretaker("serve", "--db", db_url, env=env, name="serve")
    try:
        print(web.wait_ready(60), "— Ctrl-C to stop", flush=True)
        print(
            f"  sign in as {DEMO_USER} with the password {password}  (shown once: each demo --serve sets a new one)",
            flush=True,
        )
        web.proc.wait()
    except KeyboardInterrupt:
        pass
    except ProcessFailed as exc:
        print(f"caretaker demo: the web view did not start: {exc}")
    finally:
        web.stop()


def run_demo(deployment: Deployment, args: argparse.Namespace) -> int:
    """Bring the stack up, run the procedure, check the world, write the report. Exit 0 only if all hold."""
    demo = deployment.demo
    if demo is None:
        print(f"caretaker demo: {deployment.path} has no demo: section (procedure, binding) to run")
        return 1
    db_url = args.db or DEFAULT_DB
    reports = Path(args.reports) if args.reports else REPO / "var" / "reports"
    (REPO / "var").mkdir(exist_ok=True)
    started = time.monotonic()
    stack = Stack(
        deployment,
        time_scale=args.time_scale,
        bridge_address=args.bridge_address,
        bridge_port=args.bridge_port,
        echo=args.verbose,
    )
    print(f"Starting the {deployment.name} stack: {', '.join(p.name for p in stack.parts)}", flush=True)
    try:
        stack.start()
    except StackFailed as exc:
        print(f"caretaker demo: {exc}")
        return 1
    try:
        print(
            f"[{time.monotonic() - started:7.1f} s] stack ready ({stack.bridge_url}); "
            f"running {demo.procedure.name} autonomously",
            flush=True,
        )
        run_id, status = _run_procedure(demo, stack.bridge_url, db_url, stack.env, started)
        dead = stack.dead_parts()
        if dead:
            print(f"caretaker demo: {', '.join(dead)} died during the run")
            return 1
        if status != "completed" or run_id is None:
            print(f"caretaker demo: the procedure did not complete ({status})")
            return 1
        if demo.check is not None:
            try:
                verified = WORLD_CHECKS[demo.check](deployment, stack.bridge_url, db_url, run_id)
            except EndStateError as exc:
                print(f"caretaker demo: the procedure completed but the world is wrong: {exc}")
                return 1
            for line in verified:
                print(f"  verified: {line}")
        report = caretaker("report", run_id, "--db", db_url, "--out", str(reports), env=stack.env, name="report")
        report.proc.wait()
        report.stop()
        if report.proc.returncode != 0:
            print(f"caretaker demo: the report failed:\n{report.tail()}")
            return 1
        print(f"[{time.monotonic() - started:7.1f} s] {deployment.name} demo complete; run {run_id}")
        print(f"  audit log: {db_url}")
        for line in report.output:
            print(f"  report: {line}")
        if args.serve:
            _serve(db_url, stack.env)
        return 0
    finally:
        stack.stop()


def demo_main(argv: list[str] | None = None) -> int:
    """``caretaker demo DEPLOYMENT``: bring the stack up, run its procedure autonomously, report."""
    parser = stack_options("caretaker demo")
    parser.add_argument(
        "--serve",
        action="store_true",
        help=f"leave the web view running after the procedure; sign in as {DEMO_USER} with the password "
        "it prints (a new one each time)",
    )
    parser.add_argument("--db", default=None, help="audit log SQLAlchemy URL (default: var/caretaker.db)")
    parser.add_argument("--reports", default=None, metavar="DIR", help="where the report goes (default: var/reports)")
    parser.set_defaults(time_scale=0.0)
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.INFO, format="%(message)s")
    try:
        deployment = load_deployment(args.deployment)
    except DataFileError as exc:
        print(f"caretaker demo: {exc}", file=sys.stderr)
        return 1
    return run_demo(deployment, args)
