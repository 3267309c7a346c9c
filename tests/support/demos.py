"""``caretaker demo`` as the README tells a newcomer, for the tests that run it: its output, its
audit log, and on a displaced world what perception located against where the seed put it."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from at_ros.transforms import angle_between, from_xyz_quat, from_xyz_rpy
from caretaker.processes import REPO
from pride.events import Event, EventKind
from records.audit_log import AuditLog
from sim.displacement import displaced_scene
from sim.scene import Scene, load_scene, marker_frame_pose
from support.processes import caretaker

__all__ = ["demo_events", "displaced_demo", "located_where_it_is", "run_demo", "verified"]


def run_demo(scenario: str, tmp_path: Path, env: dict[str, str], *more: str) -> list[str]:
    db = f"sqlite:///{tmp_path / 'audit.db'}"
    # As the README tells it: the shipped deployment file (the port 0: tests run side by side).
    proc = caretaker(
        "demo",
        str(REPO / "deployments" / f"{scenario}.yaml"),
        "--db",
        db,
        "--reports",
        str(tmp_path / "reports"),
        "--bridge-port",
        "0",
        *more,
        env=env,
        name=f"demo-{scenario}",
    )
    try:
        proc.proc.wait(timeout=420)
    finally:
        proc.stop()
    output = list(proc.output)
    assert proc.proc.returncode == 0, f"demo {scenario} failed:\n" + "\n".join(output[-60:])
    return output


def demo_events(tmp_path: Path) -> list[Event]:
    log = AuditLog(f"sqlite:///{tmp_path / 'audit.db'}")
    try:
        ((run_id, _, _),) = log.runs()
        return log.events(run_id)
    finally:
        log.close()


XYZRPY = ("x", "y", "z", "roll", "pitch", "yaw")


def _frame(scene: Scene, name: str) -> np.ndarray:
    pose = marker_frame_pose(scene, name)
    return from_xyz_rpy(pose.xyz, pose.rpy)


def located_where_it_is(events: list[Event], scenario: str, seed: int, max_deg: float) -> dict[str, dict]:
    """Every object the run located, each checked against where the seed put it: the located pose
    is in a frame as the drawings have it, so it must be the object's true pose in that frame
    (within 5 mm and ``max_deg``). And every registration of the run at a marked object's frame is
    either where the drawings put it (all zero: a template registered to look from there) or a
    located pose in that frame, never anything else. The located values by object."""
    nominal = load_scene(REPO / "sim" / "scenes" / f"{scenario}.yaml")
    truth = displaced_scene(nominal, seed)
    located: dict[str, dict] = {}
    for e in events:
        if (
            e.kind is not EventKind.COMMAND_RESULT
            or e.data.to_json()["command"] != "locate"
            or not e.data.to_json()["success"]
        ):
            continue
        obj, v = e.data.to_json()["args"]["object"], e.data.to_json()["values"]
        where = np.linalg.inv(_frame(nominal, v["frame"])) @ _frame(truth, obj)
        found = from_xyz_quat([v["x"], v["y"], v["z"]], [v["qx"], v["qy"], v["qz"], v["qw"]])
        mm = float(np.linalg.norm(found[:3, 3] - where[:3, 3]) * 1000)
        deg = float(np.degrees(angle_between(found, where)))
        print(f"seed {seed}: {obj} ({e.instruction}) {mm:.2f} mm, {deg:.3f} deg from the truth; {v['distance']:.2f} m")
        assert mm <= 5.0 and deg <= max_deg, f"{obj}: located {mm:.1f} mm and {deg:.2f} deg from where it is"
        located[obj] = v
    marked = {m.frame for m in nominal.markers}  # what perception can locate: the robot's own frames are fixed
    for e in events:
        if (
            e.kind is EventKind.COMMAND_RESULT
            and e.data.to_json()["command"] == "set_display_object_pose"
            and e.data.to_json()["success"]
        ):
            args = e.data.to_json()["args"]
            pose = [float(args[k]) for k in XYZRPY]
            if args["frame"] in marked and any(pose):
                assert any(
                    v["frame"] == args["frame"] and pose == pytest.approx([v[k] for k in XYZRPY])
                    for v in located.values()
                ), f"{e.instruction} registered at {args['frame']} {pose}: neither as drawn nor as located"
    return located


def verified(output: list[str]) -> list[str]:
    """The demo's world checks as it printed them, one ``verified: ...`` line each."""
    return [line.strip() for line in output if "verified:" in line]


def displaced_demo(
    scenario: str, seed: int, tmp_path: Path, env: dict[str, str], *, max_deg: float
) -> tuple[list[str], dict[str, dict]]:
    """``caretaker demo SCENARIO --displace SEED``: its world checks, and what it located, each
    checked against where the seed put it (:func:`located_where_it_is`)."""
    output = run_demo(scenario, tmp_path, env, "--displace", str(seed))
    return verified(output), located_where_it_is(demo_events(tmp_path), scenario, seed, max_deg=max_deg)
