"""``caretaker new robot NAME --urdf FILE`` and ``caretaker new template NAME --robot CONFIG``.

Adding a robot is adding files (README, "Adding a robot"); this writes them, so a new arm runs a
procedure the afternoon it arrives. ``new robot`` reads the URDF (joints, their ranges, the tool
link) and writes a folder that works at once: a scene (the robot on a pedestal in front of a
table), a robot config, a survey template, a procedure that visits its poses, a binding to the
generic AT SysRep and a deployment whose ``demo:`` runs the procedure and checks, as data, that
the tool reached every survey pose (``caretaker demo DIR/deployment.yaml``).

The survey poses come from the arm's own forward kinematics at joint configurations inside its
ranges, free of collisions in the planner's own world (the scene written here, as the planner
builds it), so every pose is one the arm can reach. Every written file is then checked as
``caretaker check`` checks it: what this writes, loads. ``new template`` writes a template
skeleton for a robot config: one object, an approach to it, to edit.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from caretaker.robot_model import RobotModel, ScaffoldError, read_robot_model
from datafile import DataFileError

__all__ = ["main"]

#: The generic AT SysRep every robot is driven through (the paper's Fig. 1).
AT_SYSREP = Path(__file__).resolve().parents[2] / "sysrep" / "affordance_templates.yaml"
#: A robot name is its ROS namespace (/NAME) and the stem of its procedure's id.
NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
BASE_HEIGHT = 0.75  # m: the robot base on its pedestal, at a workbench's height
TABLE_TOP = 0.70  # m: just below the base, so the arm reaches over it
SURVEY_POSES = 3
#: The fraction of each joint's range kept clear at both ends when sampling survey configurations.
RANGE_MARGIN = 0.1
#: m between survey poses at least, so each visit is a move of its own.
POSE_SPACING = 0.12
#: How many configurations are tried before the generator gives up on finding survey poses.
SAMPLES = 4000
DWELL_S = 1  # s the procedure holds each survey pose (a look; the demo sees the tool there)


# --- the layout ---------------------------------------------------------------------------------


@dataclass(frozen=True)
class Layout:
    """The robot on a pedestal and a table in front of it (+x), sized by the arm's reach."""

    reach: float  # m from the base to the tool along the chain: what the arm spans at most
    pedestal_side: float
    pedestal_height: float
    table_near: float  # x of the table's near and far edges
    table_far: float
    table_half_width: float

    def above_table(self, point: np.ndarray) -> bool:
        """A survey point: over the table (5 cm in from its edges), 15 cm to half a reach above it."""
        x, y, z = point
        return bool(
            self.table_near + 0.05 <= x <= self.table_far - 0.05
            and abs(y) <= self.table_half_width - 0.05
            and TABLE_TOP + 0.15 <= z <= TABLE_TOP + 0.15 + 0.5 * self.reach
        )


def _layout(model: RobotModel) -> Layout:
    """Size the pedestal to the base link and the table to the arm's reach (from the URDF at rest)."""
    import pybullet as p

    client = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(model.urdf), [0, 0, 0], useFixedBase=True, physicsClientId=client)
        index = {
            p.getJointInfo(body, i, physicsClientId=client)[12].decode(): i
            for i in range(p.getNumJoints(body, physicsClientId=client))
        }
        chain = [j.child for j in model.arm] + [model.tool_link]
        points = [np.zeros(3)] + [
            np.array(p.getLinkState(body, index[link], computeForwardKinematics=True, physicsClientId=client)[4])
            for link in chain
        ]
        low, high = p.getAABB(body, -1, physicsClientId=client)
    finally:
        p.disconnect(client)
    reach = float(sum(np.linalg.norm(b - a) for a, b in zip(points, points[1:], strict=False)))
    side = max(0.3, 1.2 * max(high[0] - low[0], high[1] - low[1]))
    near = side / 2 + 0.1
    return Layout(
        reach=reach,
        pedestal_side=side,
        # its top just below the base link's lowest point, so the two never touch
        pedestal_height=BASE_HEIGHT + min(0.0, low[2]) - 0.005,
        table_near=near,
        table_far=near + max(0.4, 0.6 * reach),
        table_half_width=max(0.3, 0.5 * reach),
    )


def _survey(scene_file: Path, robot_file: Path, layout: Layout, count: int) -> tuple[np.ndarray, list[np.ndarray]]:
    """A start configuration and ``count`` tool poses (in the robot base frame) the arm reaches.

    Configurations are drawn inside the joint ranges (clear of their ends) and kept when the
    planner's own world, built from the files written, finds them free of collisions and the
    tool over the table, apart from the poses already kept.

    Raises:
        ScaffoldError: too few such configurations (the arm cannot reach over the table).
    """
    from at_ros.collision_scene import build_planning_scene
    from at_ros.robot_config import load_robot_config
    from at_ros.transforms import from_xyz_rpy, invert
    from sim.collision_world import collision_world
    from sim.scene import load_scene

    scene = load_scene(scene_file)
    planning = build_planning_scene(load_robot_config(robot_file), collision_world(scene))
    try:
        lower, upper = planning.limits.lower, planning.limits.upper
        base = from_xyz_rpy(scene.robot.base.xyz, scene.robot.base.rpy)
        rest = np.clip(np.zeros(len(lower)), lower, upper)  # the URDF's own zero, when it is free
        start = rest if planning.is_valid(rest) else None
        rng = np.random.default_rng(1)  # the same folder from the same URDF
        margin = RANGE_MARGIN * (upper - lower)
        poses: list[np.ndarray] = []
        for _ in range(SAMPLES):
            q = rng.uniform(lower + margin, upper - margin)
            if not planning.is_valid(q):
                continue
            if start is None:
                start = q
                continue
            tool = planning.forward(q)
            point = tool[:3, 3]
            if layout.above_table(point) and all(
                np.linalg.norm(point - (base @ pose)[:3, 3]) >= POSE_SPACING for pose in poses
            ):
                poses.append(invert(base) @ tool)
                if len(poses) == count:
                    return start, poses
    finally:
        planning.close()
    raise ScaffoldError(
        f"found {len(poses)} of {count} collision-free survey poses over the table in {SAMPLES} configurations: "
        "is the URDF's tool link the right one (--tool-link), and its joint ranges right?"
    )


# --- the files ----------------------------------------------------------------------------------


def _numbers(values: Sequence[float] | np.ndarray, digits: int = 6) -> str:
    return "[" + ", ".join(repr(round(float(v), digits) + 0.0) for v in values) + "]"


def _path_in(target: Path, folder: Path) -> str:
    """``target`` as written in a file of ``folder``: relative inside it, else absolute."""
    target, folder = target.resolve(), folder.resolve()
    return str(target.relative_to(folder)) if target.is_relative_to(folder) else str(target)


def _scene_text(name: str, model: RobotModel, layout: Layout, start: Sequence[float] | np.ndarray, folder: Path) -> str:
    side, height = layout.pedestal_side, layout.pedestal_height
    depth, width = layout.table_far - layout.table_near, 2 * layout.table_half_width
    centre, leg = (layout.table_near + layout.table_far) / 2, TABLE_TOP - 0.04
    legs = "".join(
        f"      - {{type: box, size: [0.05, 0.05, {leg:.3f}], xyz: [{x:.3f}, {y:.3f}, {leg / 2:.3f}]}}\n"
        for x in (layout.table_near + 0.05, layout.table_far - 0.05)
        for y in (-width / 2 + 0.05, width / 2 - 0.05)
    )
    gripper = ""
    if model.gripper:
        gripper = (
            "  gripper:\n"
            f"    joints: [{', '.join(j.name for j in model.gripper)}]\n"
            f"    finger_links: [{', '.join(j.child for j in model.gripper)}]\n"
            f"    poses: {{open: {_numbers([j.upper for j in model.gripper])}, "
            f"closed: {_numbers([j.lower for j in model.gripper])}}}   # each finger joint's upper and lower limit\n"
            "    initial: open\n"
        )
    eye = (-0.6 * layout.reach - 0.5, -1.2 * layout.reach - 0.5, BASE_HEIGHT + layout.reach)
    return f"""# {name} on a pedestal in front of a table, made by `caretaker new robot` (format: sim/README.md).
# Poses are {{xyz: [m], rpy: [rad]}} in the world frame; paths are relative to this file.
name: {name}
gravity: [0.0, 0.0, -9.81]
physics_rate_hz: 240

robot:
  name: {name}
  urdf: {_path_in(model.urdf, folder)}
  base: {{xyz: [0.0, 0.0, {BASE_HEIGHT}], rpy: [0.0, 0.0, 0.0]}}
  base_link: {model.base_link}
  tool_link: {model.tool_link}
  arm_joints: [{", ".join(model.joint_names)}]
  initial_positions: {_numbers(start, 4)}
{gripper}
bodies:
  - name: pedestal
    color: [0.4, 0.4, 0.45, 1.0]
    shapes:
      - {{type: box, size: [{side:.3f}, {side:.3f}, {height:.3f}], xyz: [0.0, 0.0, {height / 2:.4f}]}}
  - name: table
    color: [0.55, 0.45, 0.35, 1.0]
    shapes:
      - {{type: box, size: [{depth:.3f}, {width:.3f}, 0.04], xyz: [{centre:.3f}, 0.0, {TABLE_TOP - 0.02:.3f}]}}
{legs}
cameras:
  - {{name: scene, eye: {_numbers(eye, 2)}, target: [{centre:.2f}, 0.0, {TABLE_TOP + 0.2:.2f}], fov_deg: 60,
     width: 320, height: 240}}
"""


def _robot_text(name: str, model: RobotModel, folder: Path) -> str:
    effector = "gripper" if model.gripper else "tool"
    ranges = "".join(f"#   {j.name}: {j.range_words()}\n" for j in model.arm)
    fingers = [j.child for j in model.gripper]
    gripper_links = f"  gripper_links: [{', '.join([*fingers, model.tool_link])}]\n" if model.gripper else ""
    return f"""# {name} as the AT server and planner see it, made by `caretaker new robot`.
# Original AT robot keys, then ours (python/at_ros/README.md). Paths are relative to this file; ROS
# names to the robot's namespace.
robot_name: {name}
planner_type: at_ros.planner_node
frame_id: robot_base
root_offset: [0.0, 0.0, 0.0, 0.0, 0.0, 0.0]
end_effector_group_map:
  - name: {effector}
    id: 0
    pose_offset: [0, 0, 0, 0, 0, 0]
    tool_offset: [0, 0, 0, 0, 0, 0]   # the control point in tool_link
end_effector_pose_map:{"" if model.gripper else "   # without fingers, these poses need no actuation"}
  - {{name: open, group: {effector}, id: 0}}
  - {{name: closed, group: {effector}, id: 1}}

urdf: {_path_in(model.urdf, folder)}
base_frame: robot_base
tool_link: {model.tool_link}
# The joint ranges, which the planner and the simulation read from the URDF:
{ranges}joint_names: [{", ".join(model.joint_names)}]
trajectory_action: arm_controller/follow_joint_trajectory
gripper_service: "{"gripper/set" if model.gripper else ""}"
halt_service: robot/halt          # stops every motion at once (AT server halt calls it)
planner:
  seed: 1
  ik_seeds: 32
  plan_time: 4.0
  velocity_scaling: 0.5
  max_acceleration: 2.0
{gripper_links}"""


def _display_object(name: str, size: Sequence[float], rgba: Sequence[float]) -> dict[str, object]:
    return {
        "name": name,
        "shape": {"type": "box", "material": {"color": "grey", "rgba": list(rgba)}, "size": list(size)},
        "origin": {"xyz": [0.0, 0.0, 0.0], "rpy": [0.0, 0.0, 0.0]},
        "controls": {"xyz": [True, True, True], "rpy": [True, True, True], "scale": 0.3},
    }


def _waypoint(display_object: str, pose: np.ndarray, ee_pose: int, planner_type: str) -> dict[str, object]:
    from at_ros.transforms import to_xyz_rpy

    xyz, rpy = to_xyz_rpy(pose)
    return {
        "ee_pose": ee_pose,
        "display_object": display_object,
        "origin": {"xyz": [round(float(v), 6) + 0.0 for v in xyz], "rpy": [round(float(v), 6) + 0.0 for v in rpy]},
        "planner_type": planner_type,
    }


def _template_text(
    name: str, objects: list[dict[str, object]], trajectories: dict[str, list[dict[str, object]]], group: int
) -> str:
    """An AT template in the original JSON (python/at_ros/README.md): one end effector group per trajectory."""
    template = {
        "name": name,
        "image": "",
        "display_objects": objects,
        "end_effector_trajectory": [
            {"name": trajectory, "end_effector_group": [{"id": group, "end_effector_waypoint": waypoints}]}
            for trajectory, waypoints in trajectories.items()
        ],
    }
    return json.dumps(template, indent=2) + "\n"


def _pose_words(pose: np.ndarray) -> tuple[str, str]:
    from at_ros.transforms import to_xyz_rpy

    xyz, rpy = to_xyz_rpy(pose)
    return _numbers(xyz), _numbers(rpy)


def _procedure_text(name: str, count: int) -> str:
    at = "survey:${survey_at.id}"
    steps = "".join(
        f"""
  <step id="pose_{k}" title="Survey pose {k}">
    <command system="affordance_templates" name="plan_trajectory">
      <text>Plan the move to survey pose {k}</text>
      <arg name="affordance_template">{at}</arg>
      <arg name="trajectory">pose_{k}</arg>
    </command>
    <verify system="affordance_templates" telemetry="plan_valid" equals="true" timeout="30"/>
    <command system="affordance_templates" name="execute_plan">
      <text>Move the tool to survey pose {k}</text>
      <arg name="affordance_template">{at}</arg>
      <arg name="trajectory">pose_{k}</arg>
    </command>
    <verify system="affordance_templates" telemetry="execute_status" equals="SUCCEEDED" timeout="120"/>
    <wait seconds="{DWELL_S}">
      <text>Hold survey pose {k} for a look</text>
    </wait>
  </step>
"""
        for k in range(1, count + 1)
    )
    return f"""<?xml version="1.0" encoding="UTF-8"?>
<!-- Made by `caretaker new robot`: {name} visits each pose of its survey template (procedures/README.md). -->
<procedure id="{name}_survey" title="Survey with {name}" version="1.0">
  <uses system="affordance_templates"/>
  <step id="prepare" title="Add the survey template">
    <verify system="affordance_templates" telemetry="affordance_template_server_active" equals="true" timeout="30"/>
    <verify system="affordance_templates" telemetry="planner_node_active" equals="true" timeout="30"/>
    <command system="affordance_templates" name="add_affordance_template" result="survey_at">
      <arg name="affordance_template">survey</arg>
      <arg name="hide_waypoints">false</arg>
    </command>
    <command system="affordance_templates" name="set_display_object_pose">
      <text>Register the survey on the robot's base</text>
      <arg name="affordance_template">{at}</arg>
      <arg name="id">${{survey_at.id}}</arg>
      <arg name="display_object">robot_base</arg>
      <arg name="frame">robot_base</arg>
      <arg name="x">0</arg> <arg name="y">0</arg> <arg name="z">0</arg>
      <arg name="roll">0</arg> <arg name="pitch">0</arg> <arg name="yaw">0</arg>
    </command>
  </step>
{steps}
  <step id="finish" title="Remove the survey template">
    <command system="affordance_templates" name="delete_affordance_template">
      <arg name="affordance_template">survey</arg>
      <arg name="id">${{survey_at.id}}</arg>
    </command>
  </step>
</procedure>
"""


def _binding_text(name: str) -> str:
    return f"""# {name} is driven through the generic AT SysRep, like every robot; made by `caretaker new robot`.
# A binding names its SysRep by path: this one is where the shipped AT SysRep was when the folder was made.
robot: {name}
rosbridge: ws://127.0.0.1:9090      # the deployment's bridge; caretaker demo/run --rosbridge give another
ledger_namespace: /{name}           # the command ledger is in the deployment's namespace
systems:
- sysrep: {AT_SYSREP}
  plugins: [at_commands, at_telemetry]
  namespace: /{name}/affordance_template_server
  options:
    stale_after: 2.0      # s without a status message before AT telemetry is stale
    call_timeout: 10.0    # s for add/delete/set-pose services
    motion_timeout: 180.0 # s for plan and execute
"""


def _deployment_text(name: str, tool_link: str, poses: list[np.ndarray]) -> str:
    checks = "".join(
        f"    - {{tool: {tool_link}, visits: {{frame: robot_base, xyz: {xyz}, rpy: {rpy}}},\n"
        "       within_mm: 5, within_deg: 2}\n"
        for xyz, rpy in map(_pose_words, poses)
    )
    return f"""# {name}'s robot side, made by `caretaker new robot`: every file it names is in this folder.
# `caretaker up deployment.yaml` starts it; `caretaker demo deployment.yaml` also runs the survey and
# checks the world (README.md, Deployments). Paths are relative to this file.
name: {name}
scene: scene.yaml
robot: robot.yaml
templates: templates
ros: {{namespace: /{name}}}             # its topics and services under /{name}, beside any other robot
bridge: {{address: 127.0.0.1, port: 9090}}   # another robot side on this host: another port, here and in the binding
time_scale: 1.0                       # real time for `caretaker up`; `caretaker demo` runs as fast as it can
simulator: true                       # pybullet, not the robot: drafts may run here as rehearsals
critical_commanding: {{level: hazardous, approval_expires_s: 300}}   # hazardous commands need a second operator
bindings: [binding.yaml]
demo:
  procedure: survey.xml
  binding: binding.yaml
  checks:                             # the tool reached each survey pose (the template's waypoints, robot_base frame)
{checks}"""


def _write_new(files: dict[Path, str]) -> None:
    """Write ``files`` (path -> text), none of which may exist yet."""
    existing = [path for path in files if path.exists()]
    if existing:
        raise ScaffoldError(f"{existing[0]} exists; name a new folder or file (nothing was written)")
    for path, text in files.items():
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)


def _check_written(paths: Sequence[Path]) -> None:
    """Every file checks as ``caretaker check`` checks it (a failure is a bug here: say so)."""
    from caretaker.check import check_file
    from procedure_language.diagnostics import ProcedureError

    for path in paths:
        try:
            check_file(path)
        except (DataFileError, ProcedureError) as exc:
            raise ScaffoldError(f"a file written does not check (please report it): {exc}") from None


def new_robot(
    name: str, urdf: Path, folder: Path, *, tool_link: str | None, gripper: Sequence[str], poses: int
) -> list[Path]:
    """Write a working robot folder for ``urdf`` (see the module's docstring); the files written.

    Raises:
        ScaffoldError, DataFileError: what is wrong with the arguments or the URDF; nothing is
            left in ``folder`` then.
    """
    if not NAME.match(name):
        raise ScaffoldError(
            f"{name!r} cannot name a robot: it is its ROS namespace (a letter, then letters, digits, _)"
        )
    model = read_robot_model(urdf.resolve(), tool_link, gripper)
    layout = _layout(model)
    scene, robot = folder / "scene.yaml", folder / "robot.yaml"
    others = [folder / file for file in ("templates/survey.json", "survey.xml", "binding.yaml", "deployment.yaml")]
    taken = [path for path in (scene, robot, *others) if path.exists()]
    if taken:
        raise ScaffoldError(f"{taken[0]} exists; give --into a new folder (nothing was written)")
    # The survey is found in the planner's own world, built from the scene and robot config as
    # written; the scene is then written again, starting where the survey found the arm free.
    made_folder = not folder.exists()
    _write_new(
        {
            scene: _scene_text(name, model, layout, [0.0] * len(model.arm), folder),
            robot: _robot_text(name, model, folder),
        }
    )
    try:
        start, survey = _survey(scene, robot, layout, poses)
    except BaseException:
        scene.unlink()
        robot.unlink()
        if made_folder:
            folder.rmdir()
        raise
    scene.write_text(_scene_text(name, model, layout, start, folder))
    waypoints = {f"pose_{k}": [_waypoint("robot_base", pose, 0, "JOINT")] for k, pose in enumerate(survey, 1)}
    robot_base = _display_object("robot_base", (0.2, 0.2, 0.05), (0.6, 0.6, 0.6, 0.4))
    template, procedure, binding, deployment = others
    _write_new(
        {
            template: _template_text("survey", [robot_base], waypoints, 0),
            procedure: _procedure_text(name, len(survey)),
            binding: _binding_text(name),
            deployment: _deployment_text(name, model.tool_link, survey),
        }
    )
    written = [scene, robot, template, procedure, binding, deployment]
    _check_written(written)
    return written


def new_template(name: str, robot_file: Path, folder: Path | None) -> Path:
    """Write template ``name`` for the robot config ``robot_file``: one object and an approach to it
    (a JOINT move to 20 cm in front of it, then a straight line to 10 cm), to edit; its path.

    ``folder`` defaults to ``templates/`` beside the robot config, where its deployment looks.

    Raises:
        ScaffoldError, DataFileError: a bad name or robot config, or the file exists already.
    """
    from at_ros.robot_config import load_robot_config
    from at_ros.transforms import from_xyz_rpy

    if not NAME.match(name):
        raise ScaffoldError(f"{name!r} cannot name a template: a letter, then letters, digits, _")
    config = load_robot_config(robot_file)
    effector = config.end_effectors[0]
    ee_pose = next((pose.id for pose in config.end_effector_poses if pose.group == effector.name), 0)
    path = (folder or robot_file.parent / "templates") / f"{name}.json"
    facing = (0.0, np.pi / 2, 0.0)  # the tool's z axis along the object's x: towards it from its -x side
    waypoints = [
        _waypoint("object", from_xyz_rpy((-0.2, 0.0, 0.0), facing), ee_pose, "JOINT"),
        _waypoint("object", from_xyz_rpy((-0.1, 0.0, 0.0), facing), ee_pose, "CARTESIAN"),
    ]
    text = _template_text(
        name, [_display_object("object", (0.1, 0.1, 0.1), (0.2, 0.5, 0.9, 0.5))], {"approach": waypoints}, effector.id
    )
    _write_new({path: text})
    _check_written([path])
    return path


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="caretaker new", description=__doc__.splitlines()[0])
    kinds = parser.add_subparsers(dest="kind", required=True, metavar="robot|template")
    robot = kinds.add_parser(
        "robot",
        help="a working robot folder from a URDF (scene, config, template, procedure, binding, deployment with a demo)",
    )
    robot.add_argument("name", metavar="NAME", help="the robot's name (also its ROS namespace)")
    robot.add_argument("--urdf", required=True, type=Path, metavar="FILE", help="the robot model")
    robot.add_argument(
        "--tool-link",
        metavar="LINK",
        help="the link waypoints command (default: the deepest link that is not a finger)",
    )
    robot.add_argument(
        "--gripper",
        nargs="+",
        default=[],
        metavar="JOINT",
        help="the finger joints (open at their upper limit, closed at their lower)",
    )
    robot.add_argument(
        "--into",
        type=Path,
        metavar="DIR",
        help="the folder to write (default: ./NAME); must not hold the files already",
    )
    robot.add_argument(
        "--poses", type=int, default=SURVEY_POSES, metavar="N", help=f"survey poses (default {SURVEY_POSES})"
    )
    template = kinds.add_parser("template", help="a template skeleton for a robot config (one object, an approach)")
    template.add_argument("name", metavar="NAME")
    template.add_argument(
        "--robot", required=True, type=Path, metavar="ROBOT_CONFIG", help="the robot config it is for"
    )
    template.add_argument(
        "--into",
        type=Path,
        metavar="DIR",
        help="the folder to write NAME.json in (default: templates/ beside the robot config)",
    )
    args = parser.parse_args(argv)
    try:
        if args.kind == "template":
            print(f"wrote {new_template(args.name, args.robot, args.into)}")
            return 0
        if args.poses < 1:
            parser.error("--poses must be at least 1")
        folder = args.into or Path(args.name)
        written = new_robot(
            args.name, args.urdf, folder, tool_link=args.tool_link, gripper=args.gripper, poses=args.poses
        )
    except (ScaffoldError, DataFileError) as exc:
        print(f"caretaker new: {exc}", file=sys.stderr)
        return 1
    for path in written:
        print(f"wrote {path}")
    print(f"next: caretaker demo {folder / 'deployment.yaml'}")
    return 0
