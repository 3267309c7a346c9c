"""The simulation in-process (no ROS): determinism, grasp/release physics, scene-file errors."""

from __future__ import annotations

from pathlib import Path

import pytest
from arm_paths import ArmModel

from sim.scene import SceneError, load_scene
from sim.simulation import Simulation
from sim.trajectory import validate_trajectory

HOME = [0.0, -1.9, 1.9, -1.570796, -1.570796, 0.0]


def run_to(sim: Simulation, waypoints: list[list[float]], model: ArmModel, speed: float = 0.3) -> None:
    current = tuple(sim.arm_positions)
    points = [(t, q, []) for t, q in model.timed(waypoints, current, speed)]
    run = sim.start_trajectory(
        validate_trajectory(
            list(sim.arm_joints), points, limits=sim.limits, controller_joints=sim.arm_joints, current=current
        ),
        0.0,
    )
    while not run.done.is_set():
        sim.step()
    assert run.error_code == 0, run.error_string


def set_gripper(sim: Simulation, pose: str) -> str:
    assert sim.gripper is not None
    motion = sim.gripper.start(pose)
    while not motion.done.is_set():
        sim.step()
    assert motion.success, motion.message
    return motion.message


def pick_and_drop(model: ArmModel, lift: float) -> tuple[tuple[float, ...], tuple[float, ...], str]:
    """Take the clean filter out of rack slot 1 and open the gripper ``lift`` m short of the slot."""
    sim = Simulation(load_scene("iva"), seed=3)
    try:
        line = model.slot_line("rack/slot_1", 0.15, 0.0, HOME)
        run_to(sim, [line[0]], model)
        run_to(sim, line[1:], model, 0.1)
        assert set_gripper(sim, "closed") == "closed on CDRA-F-0012"
        out = model.slot_line("rack/slot_1", 0.0, lift, line[-1])
        run_to(sim, out[1:], model, 0.1)
        message = set_gripper(sim, "open")
        for _ in range(int(2.0 / sim.dt)):  # two seconds to fall and settle
            sim.step()
        pos, orn = sim.filters.pose("CDRA-F-0012")
        return pos, orn, message
    finally:
        sim.close()


@pytest.fixture(scope="module")
def model() -> ArmModel:
    m = ArmModel("iva")
    yield m
    m.close()


def test_a_filter_released_in_the_air_falls_and_the_same_run_gives_the_same_pose(model: ArmModel) -> None:
    first = pick_and_drop(model, 0.30)
    second = pick_and_drop(model, 0.30)
    assert first[2].startswith("CDRA-F-0012 released (free)")
    pos, _, _ = first
    assert pos[2] < 0.8, f"released filter did not fall (z = {pos[2]:.3f})"
    assert first[:2] == second[:2], "two identical runs diverged"


def test_a_filter_released_inside_its_slot_is_seated(model: ArmModel) -> None:
    pos, _, message = pick_and_drop(model, 0.01)
    assert message.startswith("CDRA-F-0012 seated in rack/slot_1")
    assert pos == pytest.approx(model.scene.slots["rack/slot_1"].pose.xyz, abs=1e-6)


def test_scene_file_errors_name_the_file_line_and_key(tmp_path: Path) -> None:
    shipped = Path(__file__).resolve().parents[2] / "sim" / "scenes" / "iva.yaml"
    bad = tmp_path / "bad.yaml"
    # A scene's robot model is relative to the scene file: a copy elsewhere names it absolutely.
    text = shipped.read_text().replace("urdf: ../robots/", f"urdf: {shipped.parent.parent}/robots/")
    bad.write_text(text.replace("slot: rack/slot_2}", "slot: rack/slot_9}"))
    line = 1 + next(i for i, row in enumerate(bad.read_text().splitlines()) if "rack/slot_9" in row)
    with pytest.raises(SceneError, match=rf"bad\.yaml:{line}: filters\[1\]\.slot: unknown slot 'rack/slot_9'"):
        load_scene(bad)
    bad.write_text(text.replace("xyz: [0.0, 0.0, 0.75]", "xyz: [0.0, 0.75]"))
    with pytest.raises(SceneError, match=r"robot\.base\.xyz: expected a list of 3 numbers"):
        load_scene(bad)
    bad.write_text(text.replace("physics_rate_hz: 240", "physics_rate_hz: 240\nphysics_rate: 100"))
    with pytest.raises(SceneError, match=r"bad\.yaml:\d+: physics_rate: unknown key 'physics_rate'"):
        load_scene(bad)
    bad.write_text(shipped.read_text())
    with pytest.raises(
        SceneError, match=r"bad\.yaml:\d+: robot\.urdf: no such file: .*'\.\./robots/ur10_gripper\.urdf' relative to"
    ):
        load_scene(bad)
    with pytest.raises(SceneError, match="moon: no such scene; give a scene file or one of eva, iva"):
        load_scene("moon")


def test_held_filter_does_not_sink_while_the_arm_rests(model: ArmModel) -> None:
    sim = Simulation(load_scene("iva"), seed=3)
    try:
        line = model.slot_line("rack/slot_1", 0.15, 0.0, HOME)
        run_to(sim, [line[0]], model)
        run_to(sim, line[1:], model, 0.1)
        assert set_gripper(sim, "closed") == "closed on CDRA-F-0012"
        run_to(sim, model.slot_line("rack/slot_1", 0.0, 0.15, line[-1])[1:], model, 0.1)
        held_at, _ = sim.filters.pose("CDRA-F-0012")
        for _ in range(int(5.0 / sim.dt)):  # five seconds at rest under gravity
            sim.step()
        rested_at, _ = sim.filters.pose("CDRA-F-0012")
        assert max(abs(a - b) for a, b in zip(held_at, rested_at, strict=False)) < 1e-4, (held_at, rested_at)
    finally:
        sim.close()


def test_halt_stops_the_arm_and_the_fingers_where_they_are(model: ArmModel) -> None:
    """The hardware stop (robot/halt): nothing moves from the next step on, and a new goal runs."""
    from sim.trajectory import ErrorCode

    sim = Simulation(load_scene("iva"), seed=3)
    try:
        current = tuple(sim.arm_positions)
        goal = [current[0] + 1.0, *current[1:]]
        run = sim.start_trajectory(
            validate_trajectory(
                list(sim.arm_joints),
                [(10.0, goal, [])],
                limits=sim.limits,
                controller_joints=sim.arm_joints,
                current=current,
            ),
            0.0,
        )
        assert sim.gripper is not None
        fingers = sim.gripper.start("closed")
        for _ in range(20):
            sim.step()
        stopped = sim.halt("operator pressed Halt")
        assert [s.split(" ")[1] for s in stopped] == ["arm", "gripper"], stopped
        assert (
            run.done.is_set()
            and run.error_code == ErrorCode.HALTED
            and run.error_string == "halted: operator pressed Halt"
        )
        assert fingers.done.is_set() and not fingers.success and "halted: operator pressed Halt" in fingers.message
        arm, gripper = list(sim.arm_positions), list(sim.gripper.positions)
        assert current[0] < arm[0] < goal[0] - 0.5, "halted part way"
        for _ in range(240):  # a second later: no drift, no "finishing the segment"
            sim.step()
        assert sim.arm_positions == arm and sim.gripper.positions == gripper and not sim.moving
        # fingers halted part way closed hold nothing, yet did not miss a grasp: a slip monitor
        # watching for "empty" must not take the operator's halt for a slip
        assert sim.gripper.grasp_state() == "halted"
        assert sim.halt("again") == []  # idempotent: nothing was moving
        run_to(sim, [list(current)], model)  # the arm takes new goals after a halt
        assert set_gripper(sim, "open") == "at open" and sim.gripper.grasp_state() == "open"
    finally:
        sim.close()


def test_robot_base_frame_is_the_urdf_root_link() -> None:
    """A view draws robot_description at robot_base: that must be the URDF's root link frame,
    not pybullet's base inertial frame (2 cm above it on the UR10, 15 cm on the EVA arm)."""
    import xml.etree.ElementTree as ET

    import pybullet as p

    for scene_name in ("iva", "eva"):
        scene = load_scene(scene_name)
        sim = Simulation(scene)
        try:
            base_pos, base_orn = dict(sim.frames())["robot_base"]
            # The first joint's origin, as the URDF states it in the root link's frame ...
            joint = next(
                j
                for j in ET.parse(scene.robot.urdf).getroot().iter("joint")
                if j.find("parent").get("link") == scene.robot.base_link
            )
            origin = [float(v) for v in joint.find("origin").get("xyz").split()]
            expected, _ = p.multiplyTransforms(base_pos, base_orn, origin, [0, 0, 0, 1])
            # ... is where the simulation has the child link's frame.
            child = sim.world.link_index[joint.find("child").get("link")]
            actual = p.getLinkState(sim.robot, child, computeForwardKinematics=True, physicsClientId=sim.client)[4]
            assert max(abs(a - b) for a, b in zip(expected, actual, strict=False)) < 1e-6, (
                scene_name,
                expected,
                actual,
            )
        finally:
            sim.close()
