"""``caretaker new robot`` and ``caretaker new template`` write files that load, and poses the arm reaches.

On a URDF no shipped file uses (pybullet's KUKA iiwa, 7 DOF): every file written passes
``caretaker check``; the joint ranges written are the URDF's; each survey pose resolves, through
the AT server's own template instance, to a tool goal the planner's IK reaches inside the joint
ranges without collision; the deployment's checks name exactly those poses. Mistakes are one line
saying what to give instead, and nothing is left behind.
"""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pybullet_data
import pytest

from caretaker.deployment import load_deployment
from caretaker.world_checks import FrameCheck

REPO = Path(__file__).resolve().parents[2]
IIWA = Path(pybullet_data.getDataPath()) / "kuka_iiwa" / "model.urdf"
PANDA = Path(pybullet_data.getDataPath()) / "franka_panda" / "panda.urdf"


def _caretaker(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    # a hang, not a speed: a search of 4000 configurations ran past 120 s beside a whole suite
    return subprocess.run(
        [sys.executable, "-m", "caretaker.cli", *args], capture_output=True, text=True, timeout=360, cwd=cwd
    )


@pytest.fixture(scope="module")
def iiwa(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("robots") / "iiwa"
    made = _caretaker("new", "robot", "iiwa", "--urdf", str(IIWA), "--into", str(folder), cwd=folder.parent)
    assert made.returncode == 0, made.stderr
    assert made.stdout.splitlines()[-1] == f"next: caretaker demo {folder / 'deployment.yaml'}"
    return folder


def test_no_shipped_file_uses_the_urdf() -> None:
    shipped = subprocess.run(
        ["git", "-C", str(REPO), "grep", "--untracked", "-l", "kuka_iiwa", "--", ":!tests"],
        capture_output=True,
        text=True,
    )
    assert shipped.returncode == 1 and shipped.stdout == ""  # found nowhere outside the tests


def test_every_file_written_checks(iiwa: Path) -> None:
    files = sorted(p for p in iiwa.rglob("*") if p.is_file())
    assert [p.relative_to(iiwa).as_posix() for p in files] == [
        "binding.yaml",
        "deployment.yaml",
        "robot.yaml",
        "scene.yaml",
        "survey.xml",
        "templates/survey.json",
    ]
    checked = _caretaker("check", *map(str, files), cwd=iiwa)
    assert checked.returncode == 0, checked.stdout
    assert len(checked.stdout.splitlines()) == 6 and all(": ok (" in line for line in checked.stdout.splitlines())


def test_the_joint_ranges_are_the_urdfs(iiwa: Path) -> None:
    text = (iiwa / "robot.yaml").read_text()
    assert "#   lbr_iiwa_joint_2: [-2.0944, 2.0944] rad" in text  # <limit lower="-2.09439510239" ...>
    assert "#   lbr_iiwa_joint_7: [-3.0543, 3.0543] rad" in text


def test_the_arm_reaches_every_survey_pose_and_the_checks_name_them(iiwa: Path) -> None:
    from at_ros.collision_scene import build_planning_scene
    from at_ros.ik import IkSolver
    from at_ros.instance import Registration, TemplateInstance
    from at_ros.library import load_template
    from at_ros.robot_config import load_robot_config
    from at_ros.transforms import from_xyz_rpy
    from sim.collision_world import collision_world
    from sim.scene import load_scene

    config = load_robot_config(iiwa / "robot.yaml")
    scene = load_scene(iiwa / "scene.yaml")
    base = from_xyz_rpy(scene.robot.base.xyz, scene.robot.base.rpy)
    template = load_template(iiwa / "templates" / "survey.json")
    instance = TemplateInstance(template, 0, config, np.eye(4))
    instance.register("robot_base", Registration("robot_base", np.eye(4), base))  # as the procedure registers it
    demo = load_deployment(iiwa / "deployment.yaml").demo
    assert demo is not None and demo.procedure == iiwa / "survey.xml"
    assert all(isinstance(c, FrameCheck) and c.subject == "lbr_iiwa_link_7" and c.during_run for c in demo.checks)
    planning = build_planning_scene(config, collision_world(scene))
    try:
        start = np.array(scene.robot.initial_positions)
        assert planning.is_valid(start)
        solver = IkSolver(planning, seeds=32)
        names = template.trajectory_names
        assert names == ["pose_1", "pose_2", "pose_3"] and len(demo.checks) == 3
        for name, check in zip(names, demo.checks, strict=True):
            goal = instance.resolve(instance.trajectory(name), config.end_effectors[0])[0].tool_goal
            solved = solver.solve(goal, start)
            assert isinstance(solved, np.ndarray), (name, solved)
            assert planning.within_limits(solved) and planning.is_valid(solved)
            assert np.linalg.norm(planning.forward(solved)[:3, 3] - goal[:3, 3]) < 1e-3
            assert isinstance(check, FrameCheck)
            # the check's pose is the waypoint's, in the same frame
            assert np.allclose(check.place.world({"robot_base": base}), goal, atol=1e-5)
            assert goal[2, 3] > 0.70 + 0.1  # over the table top
    finally:
        planning.close()


def test_a_gripper_is_read_from_its_joints(tmp_path: Path) -> None:
    made = _caretaker(
        "new",
        "robot",
        "panda",
        "--urdf",
        str(PANDA),
        "--gripper",
        "panda_finger_joint1",
        "panda_finger_joint2",
        "--into",
        str(tmp_path / "panda"),
        cwd=tmp_path,
    )
    assert made.returncode == 0, made.stderr
    scene = (tmp_path / "panda" / "scene.yaml").read_text()
    assert "    finger_links: [panda_leftfinger, panda_rightfinger]\n" in scene
    assert "    poses: {open: [0.04, 0.04], closed: [0.0, 0.0]}" in scene  # the joints' <limit upper/lower>
    robot = (tmp_path / "panda" / "robot.yaml").read_text()
    assert 'gripper_service: "gripper/set"' in robot and "tool_link: panda_grasptarget" in robot


def test_a_template_skeleton_for_a_robot_config(iiwa: Path) -> None:
    made = _caretaker("new", "template", "inspect_part", "--robot", str(iiwa / "robot.yaml"), cwd=iiwa)
    assert made.returncode == 0, made.stderr
    path = iiwa / "templates" / "inspect_part.json"
    assert made.stdout.strip() == f"wrote {path}"
    template = json.loads(path.read_text())
    assert [t["name"] for t in template["end_effector_trajectory"]] == ["approach"]
    assert _caretaker("check", str(path), cwd=iiwa).returncode == 0
    again = _caretaker("new", "template", "inspect_part", "--robot", str(iiwa / "robot.yaml"), cwd=iiwa)
    assert (
        again.returncode == 1
        and again.stderr == f"caretaker new: {path} exists; name a new folder or file (nothing was written)\n"
    )
    path.unlink()  # the module's other tests see the folder as made


@pytest.mark.parametrize(
    ("args", "said"),
    [
        (["robot", "9lives", "--urdf", str(IIWA)], "'9lives' cannot name a robot: it is its ROS namespace"),
        (
            ["robot", "arm", "--urdf", str(IIWA), "--tool-link", "hand"],
            "has no link 'hand'; its links are lbr_iiwa_link_0",
        ),
        (["robot", "arm", "--urdf", str(IIWA), "--gripper", "finger"], "has no moving joint 'finger'"),
        (["robot", "arm", "--urdf", str(IIWA), "--tool-link", "lbr_iiwa_link_0"], "no joint of model.urdf moves"),
        (["template", "t", "--robot", "nowhere.yaml"], "nowhere.yaml: cannot read"),
        (  # a tool on the first link never gets over the table: the scene and config it wrote go again
            ["robot", "arm", "--urdf", str(IIWA), "--tool-link", "lbr_iiwa_link_1"],
            "found 0 of 3 collision-free survey poses over the table in 4000 configurations",
        ),
    ],
)
def test_a_mistake_is_one_line_and_leaves_nothing(tmp_path: Path, args: list[str], said: str) -> None:
    made = _caretaker("new", *args, "--into", str(tmp_path / "out"), cwd=tmp_path)
    assert made.returncode == 1 and said in made.stderr, made.stderr
    ours = [line for line in made.stderr.splitlines() if not line.startswith("pybullet build time:")]  # its banner
    assert len(ours) == 1 and ours[0].startswith("caretaker new: "), made.stderr
    assert not (tmp_path / "out").exists()


def test_a_folder_holding_the_files_is_not_overwritten(iiwa: Path) -> None:
    before = (iiwa / "scene.yaml").read_text()
    made = _caretaker("new", "robot", "iiwa", "--urdf", str(IIWA), "--into", str(iiwa), cwd=iiwa)
    assert made.returncode == 1 and f"{iiwa / 'scene.yaml'} exists; give --into a new folder" in made.stderr
    assert (iiwa / "scene.yaml").read_text() == before
