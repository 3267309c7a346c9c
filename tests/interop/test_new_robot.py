"""A robot Caretaker does not ship, added by files only, completes a procedure (issue 18, Done when).

The files of tests/fixtures/bench_arm are copied to a folder outside the checkout, as a user would
write them: a 6-DOF arm with a spherical wrist and other link lengths than the UR10 (URDF), a
workbench scene of its own, a robot config, an AT template, a procedure, a binding to the generic
AT SysRep and a deployment (in ROS namespace /bench). ``caretaker check`` accepts them all;
``caretaker up DEPLOYMENT`` starts the robot side (real simulation, planner with OMPL, AT server,
rosbridge); ``caretaker run`` completes the procedure through the Java PAX plugins; the part is
then in the slot the procedure named, as the simulation itself reports it; and nothing in the
checkout changed. The arm's wrist pitch range excludes the IK solution nearest to its start
(asserted below), so the procedure completes only because IK respects the limits while solving.
"""

from __future__ import annotations

import math
import shutil
import threading
from pathlib import Path
from urllib.parse import urlparse

import numpy as np
import pytest
import roslibpy

from caretaker.processes import REPO, caretaker
from support.checkout import checkout_status
from support.stack import stack_up

pytestmark = [pytest.mark.ros, pytest.mark.slow]

FIXTURE = REPO / "tests" / "fixtures" / "bench_arm"
GENERIC_AT_SYSREP = REPO / "sysrep" / "affordance_templates.yaml"
SLOT_A, SLOT_B = "shelf/slot_a", "shelf/slot_b"
NAMESPACE = "/bench"  # the deployment's: this robot's topics and services live under it


@pytest.fixture
def robot_folder(tmp_path: Path) -> Path:
    """The user's files, in a folder of their own outside the checkout."""
    folder = tmp_path / "bench"
    shutil.copytree(FIXTURE, folder)
    binding = folder / "binding.yaml"
    binding.write_text(binding.read_text().replace("AT_SYSREP", str(GENERIC_AT_SYSREP)))
    assert REPO not in folder.resolve().parents
    return folder


def _frames(url: str, timeout: float = 30.0) -> dict[str, tuple[float, float, float]]:
    """Where the simulation says every named frame is, read through rosbridge as a ground client would."""
    parsed = urlparse(url)
    ros = roslibpy.Ros(host=parsed.hostname, port=parsed.port)
    ros.run(timeout)
    arrived, received = threading.Event(), {}

    def take(message: dict) -> None:
        received.update(message)
        arrived.set()

    topic = roslibpy.Topic(ros, f"{NAMESPACE}/sim/frames", "caretaker_sim_msgs/NamedPoses")
    topic.subscribe(take)
    try:
        assert arrived.wait(timeout), f"no {NAMESPACE}/sim/frames through rosbridge"
    finally:
        topic.unsubscribe()
        ros.close()
    return {
        name: tuple(pose["position"][k] for k in "xyz")
        for name, pose in zip(received["names"], received["poses"], strict=True)
    }


def test_the_wrist_range_excludes_the_ik_solution_nearest_the_start(robot_folder: Path) -> None:
    """What makes the limits matter: pybullet's solver, which ignores limits, answers the first
    grasp waypoint from the arm's start with the wrist pitched outside its range."""
    from at_ros.collision_scene import build_planning_scene
    from at_ros.ik import IkSolver
    from at_ros.instance import Registration, TemplateInstance
    from at_ros.library import load_template
    from at_ros.robot_config import load_robot_config
    from at_ros.transforms import from_xyz_rpy
    from sim.collision_world import collision_world
    from sim.scene import load_scene

    config = load_robot_config(robot_folder / "bench_arm.yaml")
    scene = load_scene(robot_folder / "workbench.yaml")
    planning = build_planning_scene(config, collision_world(scene))
    try:
        instance = TemplateInstance(
            load_template(robot_folder / "templates" / "relocate_part.json"), 0, config, np.eye(4)
        )
        slot = scene.slots[SLOT_A].pose
        instance.register("part", Registration("world", np.eye(4), from_xyz_rpy(slot.xyz, slot.rpy)))
        trajectory = instance.trajectory("move_part")
        goal = instance.resolve(trajectory, config.end_effectors[0])[0].tool_goal
        solver = IkSolver(planning, seeds=32)
        start = np.array(scene.robot.initial_positions)
        natural = solver._unconstrained(goal, start)
        pitch = config.joint_names.index("wrist_pitch_joint")
        assert np.linalg.norm(planning.forward(natural)[:3, 3] - goal[:3, 3]) < 1e-3  # it does reach the pose ...
        assert natural[pitch] < planning.limits.lower[pitch]  # ... outside the wrist's range
        solved = solver.solve(goal, start)
        assert isinstance(solved, np.ndarray) and planning.within_limits(solved)
    finally:
        planning.close()


def test_a_robot_added_by_files_only_completes_a_procedure(
    robot_folder: Path, ros_env: dict[str, str], tmp_path: Path
) -> None:
    before = checkout_status()
    files = [robot_folder / name for name in ("deployment.yaml", "workbench.yaml", "bench_arm.yaml", "binding.yaml")]
    check = caretaker(
        "check", *map(str, files), str(robot_folder / "templates" / "relocate_part.json"), env=ros_env, name="check"
    )
    check.proc.wait(60)
    check.stop()
    assert check.proc.returncode == 0, check.tail()

    db = f"sqlite:///{tmp_path / 'audit.db'}"
    with stack_up(robot_folder / "deployment.yaml", ros_env) as up:
        assert "READY stack bench " in up.process.tail()
        start = _frames(up.url)
        assert math.dist(start["filter/P-1"], start[SLOT_A]) < 0.01
        run = caretaker(
            "run",
            str(robot_folder / "relocate_part.xml"),
            "--binding",
            str(robot_folder / "binding.yaml"),
            "--rosbridge",
            up.url,
            "--auto",
            "--rehearsal",
            "--user",
            "integrator",
            "--db",
            db,
            env=ros_env,
            name="run",
        )
        try:
            result = run.wait_for_line(r"^RESULT ", 400)
        finally:
            run.stop()
        assert result.startswith("RESULT completed"), run.tail(80)
        end = _frames(up.url)
    # The habitat side's own account: the part is seated in slot B, slot A is empty.
    assert math.dist(end["filter/P-1"], end[SLOT_B]) < 0.01, (end["filter/P-1"], end[SLOT_B])
    assert math.dist(end["filter/P-1"], end[SLOT_A]) > 0.4
    # The deployment's own folders were used, inside the user's folder.
    assert (robot_folder / "state" / "at_server.json").is_file()
    assert checkout_status() == before
