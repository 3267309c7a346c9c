"""The planner's world where the registrations put things, not where the drawings do.

A real habitat is not its CAD model: the collision world and ``sim/frames`` say where the drawings
put the cabinet and the rack, perception finds them a few centimetres off, and the run registers
its templates there (``set_display_object_pose``). Planning to the located filter among obstacles
left at the drawings' poses fails for no reason (the grasp finds no filter where the tool closes:
the planner's is 5 cm away) or for a wrong one (a housing that is not there). So every plan
request carries the latest registration of each frame (:class:`RegisteredFrame`), and for that
plan the planner moves, by the registration's correction ``pose · against⁻¹``:

- each fixed body that carries the frame (``CollisionObject.frames``: the cabinet its slot, the
  rack its three slots), and every graspable object seated in one of that body's frames;
- each graspable object that sat where the frame was when it was registered (a filter located
  by its own markers, or seated in a registered slot), as long as it is still there: a filter
  the robot has since moved is where the world model says now.

The held object is never moved (the gripper says where it is). A graspable object's own
registration wins over its body's, whatever the order; otherwise the later registration wins.
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from at_ros.planning_scene import PlanningScene
from at_ros.transforms import angle_between, invert

__all__ = ["RegisteredFrame", "located_poses", "located_world", "SAME_POSITION_M", "SAME_ANGLE_RAD"]

#: How near an object's pose must be to a frame's to sit there: a seated filter's frame is its
#: slot's exactly, and the next slot is 25 cm away.
SAME_POSITION_M = 1e-3
SAME_ANGLE_RAD = 1e-2


@dataclass(frozen=True)
class RegisteredFrame:
    """Frame ``frame`` registered at world ``pose``, where the world model had it at ``against``."""

    frame: str
    pose: np.ndarray
    against: np.ndarray

    @property
    def correction(self) -> np.ndarray:
        """The world transform that takes the frame from where it was drawn to where it is."""
        moved: np.ndarray = self.pose @ invert(self.against)
        return moved


def _same_pose(a: np.ndarray, b: np.ndarray) -> bool:
    if np.linalg.norm(a[:3, 3] - b[:3, 3]) > SAME_POSITION_M:
        return False
    return angle_between(a, b) <= SAME_ANGLE_RAD


def located_poses(
    scene: PlanningScene,
    registered: Sequence[RegisteredFrame],
    frames: Mapping[str, np.ndarray],
    held: str | None,
) -> dict[str, np.ndarray]:
    """Where each obstacle that ``registered`` (oldest first) moves is: obstacle name -> world pose.

    ``frames``: the world model's latest poses of the named frames (``sim/frames``), which say
    where each slot of a body was drawn; ``held``: the obstacle in the gripper, if any.
    """
    loose = {name: scene.obstacle_pose(name) for name in scene.graspable if name != held}
    bodies: dict[str, np.ndarray] = {}
    own: dict[str, np.ndarray] = {}
    for registration in registered:
        for name, fixed in scene.frames_fixed.items():
            if registration.frame in fixed and name not in scene.graspable:
                bodies[name] = registration.correction
        for name, pose in loose.items():
            if _same_pose(pose, registration.against):
                own[name] = registration.correction
    seated: dict[str, np.ndarray] = {}
    for body, correction in bodies.items():
        drawn = [frames[f] for f in scene.frames_fixed[body] if f in frames]
        for name, pose in loose.items():
            if name not in own and any(_same_pose(pose, slot) for slot in drawn):
                seated[name] = correction
    moved = {name: correction @ scene.obstacle_pose(name) for name, correction in bodies.items()}
    moved.update({name: correction @ loose[name] for name, correction in (seated | own).items()})
    return moved


@contextmanager
def located_world(
    scene: PlanningScene,
    registered: Sequence[RegisteredFrame],
    frames: Mapping[str, np.ndarray],
    held: str | None,
) -> Iterator[dict[str, np.ndarray]]:
    """``scene`` with :func:`located_poses` applied while the block runs (one plan), as it was after."""
    moved = located_poses(scene, registered, frames, held)
    drawn = {name: scene.obstacle_pose(name) for name in moved}
    for name, pose in moved.items():
        scene.set_obstacle_pose(name, pose)
    try:
        yield moved
    finally:
        for name, pose in drawn.items():
            scene.set_obstacle_pose(name, pose)
