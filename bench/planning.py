"""Planning benchmark: the CDRA filter template on randomized filter poses around every slot.

For each sample a slot is chosen, and its fixture (the rack or the cabinet, with the filters
seated in it) is displaced by a random offset of up to +-5 cm and +-10 deg per axis about the
slot, so the filter pose varies while staying physically consistent with its slot. The
template is registered on that pose and both trajectories are planned from the UR10's start
pose, exactly as the planner node does it (same TemplateInstance.resolve, same MotionPlanner):
``grasp_and_pull`` on the seated filter, and ``insert_and_release`` into the emptied slot with
that filter in the gripper. Reported: success rate, and plan time per trajectory (median, p95).

Side by side in the same run, the same samples with the straight-line shortcut disabled
(every JOINT waypoint solved by RRTConnect + greedy shortcutting), to show what it buys.
Plan times are wall clock and CPU time of this process: on a shared machine the CPU time is
the planner's own cost, the wall clock also what the other processes took from it.

    .venv/bin/python bench/planning.py --samples 200
"""

from __future__ import annotations

import argparse
import statistics
import time
from collections import Counter
from dataclasses import dataclass

import numpy as np
import pybullet as p

from at_ros.collision_scene import build_planning_scene
from at_ros.ik import IkFailure, IkSolver
from at_ros.instance import Registration, TemplateInstance
from at_ros.library import default_library_path, load_library
from at_ros.motion_planner import Goal, MotionPlanner, WaypointPlanningError
from at_ros.robot_config import load_robot_configs
from at_ros.transforms import from_xyz_quat, from_xyz_rpy, invert
from sim.collision_world import collision_world
from sim.scene import filter_grasp_offset, load_scene


@dataclass
class Sample:
    slot: str
    displacement: np.ndarray  # applied to the fixture about the slot frame


@dataclass
class Outcome:
    trajectory: str
    success: bool
    seconds: float
    cpu_seconds: float
    reason: str = ""
    reachable: bool = True  # every waypoint has a collision-free IK solution


def _reachable(solver: IkSolver, goals: list[Goal], held: str) -> bool:
    """Whether every waypoint has some collision-free IK solution (searched from 64 seeds).

    A held filter is parked out of the way: detached, it would float where the tool was.
    """
    scene = solver.scene
    pose = scene.obstacle_pose(held) if held else None
    scene.detach()
    if held:
        scene.set_obstacle_pose(held, from_xyz_rpy([0.0, 0.0, -10.0], [0, 0, 0]))
    try:
        near = np.zeros(scene.dof)
        return all(not isinstance(solver.solve(g.pose, near, enough=1), IkFailure) for g in goals)
    finally:
        if held:
            scene.set_obstacle_pose(held, pose)


def _percentile(values: list[float], q: float) -> float:
    return float(np.percentile(values, q)) if values else float("nan")


def _samples(slots: list[str], count: int, rng: np.random.Generator) -> tuple[list[Sample], int]:
    """Displacements that keep the world consistent: a fixture pushed into a wall, the floor or
    the table is not a pose any filter can have, so it is drawn again. Returns the samples and
    how many draws were rejected."""
    config = load_robot_configs()["ur10"]
    scene_spec = load_scene("iva")
    planning = build_planning_scene(config, collision_world(scene_spec))
    slot_pose = {name: from_xyz_quat(s.pose.xyz, s.pose.quaternion) for name, s in scene_spec.slots.items()}
    homes = {name: planning.obstacle_pose(name) for name in ("rack", "cabinet")}

    def deepest(fixture: str) -> float:
        """Deepest penetration (m, <= 0) of the fixture into the walls, floor, table or other fixture."""
        others = ("module", "table", "rack" if fixture == "cabinet" else "cabinet")
        points = [
            c[8]
            for o in others
            for c in p.getClosestPoints(
                planning.obstacles[fixture], planning.obstacles[o], 0.0, physicsClientId=planning.client
            )
        ]
        return min(points, default=0.0)

    # The scene file mounts fixtures touching walls (the cabinet's back plate sits in the wall):
    # only displacements that push deeper than that count as impossible.
    home_depth = {name: deepest(name) for name in homes}
    out, rejected = [], 0
    while len(out) < count:
        slot = slots[len(out) % len(slots)]
        displacement = from_xyz_rpy(rng.uniform(-0.05, 0.05, 3), np.radians(rng.uniform(-10.0, 10.0, 3)))
        fixture = slot.split("/")[0]
        move = slot_pose[slot] @ displacement @ invert(slot_pose[slot])
        planning.set_obstacle_pose(fixture, move @ homes[fixture])
        clash = deepest(fixture) < home_depth[fixture] - 0.002
        planning.set_obstacle_pose(fixture, homes[fixture])
        if clash:
            rejected += 1
            continue
        out.append(Sample(slot, displacement))
    planning.close()
    return out, rejected


def run(samples: list[Sample], *, shortcut: bool) -> list[Outcome]:
    config = load_robot_configs()["ur10"]
    scene_spec = load_scene("iva")
    template = load_library(default_library_path() / "templates")["cdra_filter"]
    planning = build_planning_scene(config, collision_world(scene_spec))
    planner = MotionPlanner(planning, config.planner)
    planner.joint_planner.straight_line_first = shortcut
    reach = IkSolver(planning, seeds=64, rng=np.random.default_rng(0))
    start = np.array(scene_spec.robot.initial_positions)
    slot_pose = {name: from_xyz_quat(s.pose.xyz, s.pose.quaternion) for name, s in scene_spec.slots.items()}
    occupant = {f.slot: f"filter/{f.id}" for f in scene_spec.filters}
    spare = f"filter/{scene_spec.filters[0].id}"
    grasp = from_xyz_quat(
        filter_grasp_offset(scene_spec.filter_model).xyz, filter_grasp_offset(scene_spec.filter_model).quaternion
    )
    fixtures = {name: planning.obstacle_pose(name) for name in ("rack", "cabinet")}
    filters_home = {name: planning.obstacle_pose(name) for name in planning.graspable}
    outcomes: list[Outcome] = []
    for sample in samples:
        fixture = sample.slot.split("/")[0]
        # Move the fixture and its seated filters rigidly: slot -> slot @ displacement.
        move = slot_pose[sample.slot] @ sample.displacement @ invert(slot_pose[sample.slot])
        planning.set_obstacle_pose(fixture, move @ fixtures[fixture])
        for slot, name in occupant.items():
            if slot.startswith(fixture + "/"):
                planning.set_obstacle_pose(name, move @ filters_home[name])
        target = slot_pose[sample.slot] @ sample.displacement
        instance = TemplateInstance(template, 0, config, root_pose=np.eye(4))
        instance.register("cdra_filter", Registration("bench", np.eye(4), target))
        ee = config.end_effectors[0]
        held = occupant.get(sample.slot, spare)
        for trajectory_name in ("grasp_and_pull", "insert_and_release"):
            if trajectory_name == "grasp_and_pull":
                planning.set_obstacle_pose(held, target)
                holding = ""
            else:
                # The slot is empty; its filter is in the gripper at the grasp offset.
                planning.set_joints(start)
                planning.set_obstacle_pose(held, planning.tool_pose() @ invert(grasp))
                holding = held
            trajectory = instance.trajectory(trajectory_name)
            goals = [
                Goal(
                    w.label,
                    w.tool_goal,
                    w.waypoint.planner_type,
                    w.end_effector_pose,
                    gripper_action=w.gripper_action,
                    object_name=w.object_name,
                    object_pose=w.object_pose,
                )
                for w in instance.resolve(trajectory, ee)
            ]
            t0, c0 = time.perf_counter(), time.process_time()
            try:
                planner.plan(start, goals, held_object=holding)
                outcomes.append(Outcome(trajectory_name, True, time.perf_counter() - t0, time.process_time() - c0))
            except WaypointPlanningError as exc:
                elapsed, cpu = time.perf_counter() - t0, time.process_time() - c0
                outcomes.append(
                    Outcome(trajectory_name, False, elapsed, cpu, str(exc), reachable=_reachable(reach, goals, holding))
                )
        planning.set_obstacle_pose(fixture, fixtures[fixture])
        for name, pose in filters_home.items():
            planning.set_obstacle_pose(name, pose)
    planning.close()
    return outcomes


def report(label: str, outcomes: list[Outcome]) -> None:
    print(f"\n{label}")
    print(
        f"{'trajectory':<20} {'plans':>6} {'success':>8} {'reachable':>10} {'ok/reachable':>13} "
        f"{'median ms':>10} {'p95 ms':>8} {'cpu median':>11} {'cpu p95':>8}"
    )
    for name in ("grasp_and_pull", "insert_and_release"):
        rows = [o for o in outcomes if o.trajectory == name]
        reachable = [o for o in rows if o.reachable]
        ok = [o for o in rows if o.success]
        wall = [o.seconds * 1000 for o in ok]
        cpu = [o.cpu_seconds * 1000 for o in ok]
        print(
            f"{name:<20} {len(rows):>6} {len(ok) / len(rows):>8.1%} {len(reachable):>10} "
            f"{len(ok) / max(1, len(reachable)):>13.1%} "
            f"{statistics.median(wall):>10.1f} {_percentile(wall, 95):>8.1f} "
            f"{statistics.median(cpu):>11.1f} {_percentile(cpu, 95):>8.1f}"
        )
    failures = Counter(
        ("" if o.reachable else "[unreachable] ") + o.reason.split(": ", 1)[-1][:100] for o in outcomes if not o.success
    )
    for reason, n in failures.most_common(8):
        print(f"  failed x{n}: {reason}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--samples", type=int, default=200, help="randomized filter poses (each planned for both trajectories)"
    )
    parser.add_argument("--seed", type=int, default=11)
    parser.add_argument("--no-peer", action="store_true", help="skip the run without the straight-line shortcut")
    args = parser.parse_args()
    slots = ["rack/slot_1", "rack/slot_2", "rack/slot_3", "cabinet/slot"]
    samples, rejected = _samples(slots, args.samples, np.random.default_rng(args.seed))
    print(
        f"{args.samples} filter poses (+-5 cm, +-10 deg per axis about {', '.join(slots)}; "
        f"{rejected} draws that pushed a fixture into a wall/table redrawn), UR10 from its start pose"
    )
    report(
        "at_ros planner (IK, straight-line shortcut, else OMPL RRTConnect + greedy shortcutting)",
        run(samples, shortcut=True),
    )
    if not args.no_peer:
        report(
            "ablation: same planner, every JOINT waypoint through OMPL RRTConnect (no straight-line shortcut)",
            run(samples, shortcut=False),
        )


if __name__ == "__main__":
    main()
