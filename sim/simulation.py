"""The simulated world as the robot's hardware: one pybullet client stepped by one thread.

The arm is position-controlled perfectly (kinematically), as an industrial controller tracking
a validated trajectory would be; what the simulation adds is the world: collisions abort a
motion, filters are grasped, carried, seated and locked. Everything that touches pybullet holds
``world_lock`` because ROS callbacks (cameras, services) run on other threads than the stepper.
"""

from __future__ import annotations

import logging
import random
import threading
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import pybullet as p

from sim.cabin_air import CabinAir
from sim.cabin_knobs import set_knobs
from sim.cameras import fixed_camera_pose
from sim.cdra_cabinet import CdraCabinet
from sim.displacement import displaced_scene
from sim.filter_slots import FilterSlots, SlotBlocked
from sim.gripper import Gripper
from sim.scene import Scene, SceneError
from sim.trajectory import ErrorCode, JointLimit, Trajectory
from sim.world import World, build_world
from sim.world_lock import WorldLock

__all__ = ["Simulation", "TrajectoryRun"]

LOG = logging.getLogger(__name__)

#: Contacts deeper than this (m) are collisions; shallower ones are numerical touching.
PENETRATION = 0.001
#: Default goal tolerance (rad) when a goal gives 0.
DEFAULT_GOAL_TOLERANCE = 0.01
#: s of sim time between advances of the cabin's CO2: a lock or a seating counts at most this late.
AIR_PERIOD = 0.1

Pose = tuple[tuple[float, float, float], tuple[float, float, float, float]]


@dataclass
class TrajectoryRun:
    """One trajectory being executed by the physics thread."""

    trajectory: Trajectory
    goal_tolerance: float
    start_time: float = 0.0
    done: threading.Event = field(default_factory=threading.Event)
    error_code: int = ErrorCode.SUCCESSFUL
    error_string: str = ""
    desired: tuple[float, ...] = ()
    actual: tuple[float, ...] = ()
    elapsed: float = 0.0
    cancel_requested: bool = False


class Simulation:
    """One scene in one pybullet DIRECT client; ``step`` advances it by ``dt``.

    With ``displace`` (a seed) the physical world is ``sim.displacement.displaced_scene``: things
    are not where ``scene`` says, while :meth:`frames` still says what ``scene`` says (the world
    model) and only :meth:`true_frames` (the ground truth, for checks) says where they are.
    ``cabin``: knobs of the cabin's air by name (sim/cabin_knobs.py, values checked), for a scene
    with a CDRA cabinet.
    """

    def __init__(
        self, scene: Scene, *, seed: int = 0, displace: int | None = None, cabin: Mapping[str, float] | None = None
    ) -> None:
        if cabin and scene.cabinet is None:
            raise SceneError(scene.path, 0, "", f"no CDRA cabinet, hence no cabin air to set {', '.join(cabin)}")
        # Seeded although the dynamics are deterministic anyway: any randomness added later
        # (sensor noise, perturbations) stays reproducible under the same --seed.
        random.seed(seed)
        np.random.seed(seed)
        self.scene = scene
        self.physical = scene if displace is None else displaced_scene(scene, displace)
        self.world_lock = WorldLock()
        self.client = p.connect(p.DIRECT)
        p.setPhysicsEngineParameter(deterministicOverlappingPairs=1, physicsClientId=self.client)
        self.dt = 1.0 / scene.physics_rate_hz
        p.setTimeStep(self.dt, physicsClientId=self.client)
        self.world: World = build_world(self.physical, self.client)
        self.time = 0.0
        self.robot = self.world.robot
        self.arm_joints = tuple(scene.robot.arm_joints)
        self._arm_index = [self.world.joint_index[j] for j in self.arm_joints]
        self.limits: dict[str, JointLimit] = {}
        for name, j in self.world.joint_index.items():
            info = p.getJointInfo(self.robot, j, physicsClientId=self.client)
            if info[2] in (p.JOINT_REVOLUTE, p.JOINT_PRISMATIC):
                self.limits[name] = JointLimit(info[8], info[9], info[11])
        self.tool_link = self.world.link_index[scene.robot.tool_link]
        self.arm_positions = list(scene.robot.initial_positions)
        self.arm_velocities = [0.0] * len(self.arm_joints)
        self.cabinet = CdraCabinet(self.physical.cabinet, self.world) if self.physical.cabinet else None
        locked = self.cabinet.is_locked if self.cabinet else (lambda slot: False)
        self.filters = FilterSlots(self.physical, self.world, locked)
        self.cabin_air = (
            CabinAir.for_filters((f.id, f.condition) for f in self.physical.filters) if self.cabinet else None
        )
        if self.cabin_air is not None:
            set_knobs(self.cabin_air, cabin or {})
        self.gripper = (
            Gripper(scene.robot.gripper, self.world, self.filters, self.tool_link) if scene.robot.gripper else None
        )
        self.gripper_joints = tuple(scene.robot.gripper.joints) if scene.robot.gripper else ()
        self.run: TrajectoryRun | None = None
        self._link_names = {j: name for name, j in self.world.link_index.items()}
        self._self_pairs = self._self_collision_pairs()
        self._self_links = sorted({link for pair in self._self_pairs for link in pair})
        # The links that hold a grasped filter and may touch it: the fingers and their palm.
        self._gripper_links = set(self.gripper.fingers) if self.gripper else set()
        self._gripper_links |= {
            p.getJointInfo(self.robot, f, physicsClientId=self.client)[16] for f in self._gripper_links
        }
        self.filters.hold_kinematic(self.link_pose(self.tool_link))

    # ------------------------------------------------------------------ commands (world_lock held by caller)

    def start_trajectory(self, trajectory: Trajectory, goal_tolerance: float) -> TrajectoryRun:
        run = TrajectoryRun(trajectory, goal_tolerance or DEFAULT_GOAL_TOLERANCE, start_time=self.time)
        if self.run is not None:
            run.error_code = ErrorCode.INVALID_GOAL
            run.error_string = "another trajectory is executing; cancel it first"
            run.done.set()
            return run
        self.run = run
        return run

    def halt(self, reason: str) -> list[str]:
        """Stop every motion now: the arm holds where it is, the fingers stop where they are.

        Takes effect before the next physics step (the caller holds ``world_lock``), so nothing
        moves after this returns. Returns what was stopped (empty: nothing was moving).
        """
        stopped = []
        run = self.run
        if run is not None:
            self._set_arm(self.arm_positions, [0.0] * len(self.arm_positions))
            self._finish(run, ErrorCode.HALTED, f"halted: {reason}")
            stopped.append(f"the arm at {run.elapsed:.2f} s of its {run.trajectory.duration:.2f} s trajectory")
        if self.gripper is not None and self.gripper.moving:
            stopped.append(self.gripper.halt(reason))
        return stopped

    # ------------------------------------------------------------------ state

    @property
    def moving(self) -> bool:
        return self.run is not None or (self.gripper is not None and self.gripper.moving)

    @property
    def busy(self) -> bool:
        """Something changes with time: the stepper should not idle."""
        return self.moving or self.filters.moving_free()

    def link_pose(self, link: int) -> Pose:
        if link == -1:
            pos, orn = p.getBasePositionAndOrientation(self.robot, physicsClientId=self.client)
            return tuple(pos), tuple(orn)  # type: ignore[return-value]
        state = p.getLinkState(self.robot, link, computeForwardKinematics=True, physicsClientId=self.client)
        return tuple(state[4]), tuple(state[5])  # type: ignore[return-value]

    def joint_state(self) -> tuple[list[str], list[float], list[float]]:
        names = list(self.arm_joints) + list(self.gripper_joints)
        positions = list(self.arm_positions) + (list(self.gripper.positions) if self.gripper else [])
        velocities = list(self.arm_velocities) + (list(self.gripper.velocities) if self.gripper else [])
        return names, positions, velocities

    def frames(self) -> list[tuple[str, Pose]]:
        """Every named frame as the robot side knows it (docs/interfaces.md, /sim/frames): the
        robot, its tool and cameras, and a held or free filter where they are; slots, targets
        and seated filters where the scene file puts them (on a displaced world, not where they are)."""
        return self._frames(truth=False)

    def true_frames(self) -> list[tuple[str, Pose]]:
        """Every named frame where it is (sim/check/frames): the ground truth, for checks only."""
        return self._frames(truth=True)

    def _frames(self, *, truth: bool) -> list[tuple[str, Pose]]:
        # The base link's frame as the URDF has it (pybullet's base pose is its inertial frame),
        # so a view drawing robot_description at robot_base puts every link where it is.
        base = self.scene.robot.base
        out: list[tuple[str, Pose]] = [
            ("robot_base", (base.xyz, base.quaternion)),
            (self.scene.robot.tool_link, self.link_pose(self.tool_link)),
        ]
        if "flange" in self.world.link_index:
            out.append(("flange", self.link_pose(self.world.link_index["flange"])))
        scene = self.physical if truth else self.scene
        slots = {name: (s.pose.xyz, s.pose.quaternion) for name, s in scene.slots.items()}
        for fid, state in self.filters.filters.items():
            seated = state.slot is not None and not state.held
            out.append((f"filter/{fid}", slots[state.slot] if seated else self.filters.pose(fid)))  # type: ignore[index]
        out += list(slots.items())
        for t in scene.targets:
            out.append((f"target/{t.name}", (t.pose.xyz, t.pose.quaternion)))
        for cam in self.scene.cameras.values():
            pose = self.link_pose(self.world.link_index[cam.link]) if cam.link else fixed_camera_pose(cam)
            out.append((f"camera/{cam.name}", pose))
        return out

    def held_object(self) -> str:
        held = self.filters.held()
        return held.id if held else ""

    # ------------------------------------------------------------------ stepping

    def step(self) -> None:
        """Advance the world by one physics step (caller holds ``world_lock``)."""
        previous = list(self.arm_positions)
        run = self.run
        if run is not None:
            self._advance_arm(run)
        if self.gripper is not None:
            self.gripper.step(self.dt)
        if run is not None and not run.done.is_set():
            problem = self._held_filter_problem() or self._collision()
            if problem is not None:
                code, message = problem
                self._set_arm(previous, [0.0] * len(previous))
                self._held_filter_problem()  # put the held filter back with the arm
                self._finish(run, code, message)
            elif run.elapsed >= run.trajectory.duration:
                self._finish_at_goal(run)
        p.stepSimulation(physicsClientId=self.client)
        self._set_arm(self.arm_positions, self.arm_velocities)  # undo what gravity did to the arm
        if self.gripper is not None:
            for joint, q in zip(self.gripper.joints, self.gripper.positions, strict=False):
                p.resetJointState(self.robot, joint, q, physicsClientId=self.client)
        self.filters.hold_kinematic(self.link_pose(self.tool_link))
        self.time += self.dt
        self._breathe()

    def rest(self, steps: int) -> None:
        """Let ``steps`` physics steps of time pass in a world at rest (not :attr:`busy`, and settled):
        only the clock moves. Stepping bodies that do not move would change nothing but the CPU
        spent (caller holds ``world_lock``)."""
        self.time += steps * self.dt
        self._breathe()

    def _breathe(self) -> None:
        """Advance the cabin's CO2 to now, with the filter seated and locked in the cabinet removing it."""
        air, cabinet = self.cabin_air, self.cabinet
        if air is None or cabinet is None or self.time - air.time < AIR_PERIOD:
            return
        seated = self.filters.in_slot(cabinet.slot)
        air.advance(self.time, seated.id if seated is not None and cabinet.locked else None)

    def _advance_arm(self, run: TrajectoryRun) -> None:
        # The trajectory's clock stops at its end: a clock summed from steps can pass the end by a
        # rounding error plus a step, and a client would read a time its trajectory does not have.
        elapsed = min(self.time + self.dt - run.start_time, run.trajectory.duration)
        desired, velocity = run.trajectory.sample(elapsed)
        if run.cancel_requested:
            self._set_arm(self.arm_positions, [0.0] * len(self.arm_positions))
            # Not a success: the arm stopped short of the trajectory's end, and a client that read
            # only the code would plan its next motion from a goal the arm never reached.
            self._finish(
                run,
                ErrorCode.HALTED,
                f"cancelled after {run.elapsed:.2f} s of its {run.trajectory.duration:.2f} s "
                "trajectory: the arm stopped short of its goal",
            )
            return
        self._set_arm(list(desired), list(velocity))
        run.desired, run.actual, run.elapsed = tuple(desired), tuple(self.arm_positions), elapsed

    def _finish_at_goal(self, run: TrajectoryRun) -> None:
        error = max(abs(a - b) for a, b in zip(self.arm_positions, run.trajectory.final, strict=False))
        if error > run.goal_tolerance:
            self._finish(
                run,
                ErrorCode.GOAL_TOLERANCE_VIOLATED,
                f"final error {error:.4f} rad exceeds the goal tolerance {run.goal_tolerance:.4f} rad",
            )
        else:
            self._finish(
                run, ErrorCode.SUCCESSFUL, f"reached the goal in {run.elapsed:.3f} s (max joint error {error:.5f} rad)"
            )

    def _finish(self, run: TrajectoryRun, code: int, message: str) -> None:
        run.error_code = code
        run.error_string = message
        run.actual = tuple(self.arm_positions)
        self.arm_velocities = [0.0] * len(self.arm_velocities)
        if self.run is run:
            self.run = None
        log = LOG.info if code == ErrorCode.SUCCESSFUL else LOG.warning
        log("trajectory finished (%d): %s", code, message)
        run.done.set()

    def _set_arm(self, positions: list[float], velocities: list[float]) -> None:
        self.arm_positions = list(positions)
        self.arm_velocities = list(velocities)
        for j, q, v in zip(self._arm_index, positions, velocities, strict=False):
            p.resetJointState(self.robot, j, q, v, physicsClientId=self.client)

    def _held_filter_problem(self) -> tuple[int, str] | None:
        try:
            self.filters.follow(self.link_pose(self.tool_link))
        except SlotBlocked as exc:
            return ErrorCode.PATH_TOLERANCE_VIOLATED, str(exc)
        return None

    def _collision(self) -> tuple[int, str] | None:
        """The first unexpected contact of the robot (or what it holds) with the world."""
        p.performCollisionDetection(physicsClientId=self.client)
        held = self.filters.held()
        held_body = held.body if held else None
        robot_name = self.scene.robot.name
        for c in p.getContactPoints(bodyA=self.robot, physicsClientId=self.client):
            other, link, depth = c[2], c[3], c[8]
            if depth > -PENETRATION or link == -1 or other == self.robot or other == held_body:
                continue
            return (
                ErrorCode.COLLISION,
                f"collision: {robot_name}/{self._link_names.get(link, link)} hit {self.world.body_name(other)} "
                f"({-depth * 1000:.1f} mm deep)",
            )
        # Exact distance queries are costly; only pairs whose bounding boxes overlap need one.
        boxes = {link: p.getAABB(self.robot, link, physicsClientId=self.client) for link in self._self_links}
        for a, b in self._self_pairs:
            (amin, amax), (bmin, bmax) = boxes[a], boxes[b]
            if any(amin[k] > bmax[k] or bmin[k] > amax[k] for k in range(3)):
                continue
            points = p.getClosestPoints(
                self.robot, self.robot, -PENETRATION, linkIndexA=a, linkIndexB=b, physicsClientId=self.client
            )
            if points:
                return ErrorCode.COLLISION, (
                    f"self-collision: {robot_name}/{self._link_names.get(a, a)} "
                    f"hit {robot_name}/{self._link_names.get(b, b)} "
                    f"({-points[0][8] * 1000:.1f} mm deep)"
                )
        if held_body is not None:
            for c in p.getContactPoints(bodyA=held_body, physicsClientId=self.client):
                other, other_link, depth = c[2], c[4], c[8]
                if depth > -PENETRATION or (other == self.robot and other_link in self._gripper_links):
                    continue
                what = (
                    f"{robot_name}/{self._link_names.get(other_link, other_link)}"
                    if other == self.robot
                    else self.world.body_name(other)
                )
                return ErrorCode.COLLISION, f"collision: held filter/{held.id} hit {what} ({-depth * 1000:.1f} mm deep)"  # type: ignore[union-attr]
        return None

    def _self_collision_pairs(self) -> list[tuple[int, int]]:
        """Link pairs of the robot that must never touch.

        Left out, as MoveIt's allowed-collision matrix would: links joined by a joint, pairs
        already touching in the initial configuration (e.g. the gripper bolted to the wrist),
        and the gripper's own parts (fingers touch each other when closed).
        """
        robot, client = self.robot, self.client
        with_shapes = [
            link
            for link in [-1, *range(p.getNumJoints(robot, physicsClientId=client))]
            if p.getCollisionShapeData(robot, link, physicsClientId=client)
        ]
        parent = {
            j: p.getJointInfo(robot, j, physicsClientId=client)[16]
            for j in range(p.getNumJoints(robot, physicsClientId=client))
        }
        gripper = set(self.gripper.fingers) if self.gripper else set()
        if gripper:
            gripper |= {parent[f] for f in gripper}
        pairs = []
        for i, a in enumerate(with_shapes):
            for b in with_shapes[i + 1 :]:
                if parent.get(b) == a or parent.get(a) == b or (a in gripper and b in gripper):
                    continue
                if p.getClosestPoints(robot, robot, 0.0, linkIndexA=a, linkIndexB=b, physicsClientId=client):
                    continue
                pairs.append((a, b))
        return pairs

    def close(self) -> None:
        p.disconnect(physicsClientId=self.client)
        if self.world.marker_textures is not None:
            self.world.marker_textures.close()
