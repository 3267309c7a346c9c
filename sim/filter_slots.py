"""Where every CDRA filter is: seated in a slot, held by the gripper, or free.

Seated and held filters are placed kinematically every step (a seated cartridge is held by its
rails, a held one by the fingers); free filters are left to the physics engine. Locks are the
cabinet's business: this module asks a ``is_locked(slot)`` callable before letting a filter
leave or enter a slot.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass

import pybullet as p

from sim.scene import Scene
from sim.world import World

__all__ = ["FilterSlots", "FilterState", "SlotBlocked"]

LOG = logging.getLogger(__name__)

#: A seated filter counts as pulled once its commanded pose is this far (m) from the slot.
UNSEAT_DISTANCE = 0.005
#: A released filter seats itself when this close to an empty slot's pose (m, rad).
CAPTURE_AXIAL = 0.03
CAPTURE_LATERAL = 0.02
CAPTURE_ANGLE = 0.12
#: The part of a slot's approach (m in front of the seated pose, and half-width) a latch guards.
LATCH_DEPTH = 0.20
LATCH_HALF_WIDTH = 0.08

Vec3 = tuple[float, float, float]
Quat = tuple[float, float, float, float]


class SlotBlocked(RuntimeError):
    """A held filter was moved against a locked slot (pulled out of it or pushed into it)."""


@dataclass
class FilterState:
    id: str
    condition: str
    body: int
    slot: str | None  # seated in this slot
    held: bool = False
    grasp: tuple[Vec3, Quat] | None = None  # filter pose in the tool frame while held


class FilterSlots:
    """Filters and slots of one world; all calls under the simulation's world lock."""

    def __init__(self, scene: Scene, world: World, is_locked: Callable[[str], bool]) -> None:
        self._client = world.client
        self._is_locked = is_locked
        self.slot_poses: dict[str, tuple[Vec3, Quat]] = {
            name: (s.pose.xyz, s.pose.quaternion) for name, s in scene.slots.items()
        }
        self.filters: dict[str, FilterState] = {
            f.id: FilterState(f.id, f.condition, world.filters[f.id], f.slot) for f in scene.filters
        }

    # ------------------------------------------------------------------ queries

    def in_slot(self, slot: str) -> FilterState | None:
        return next((f for f in self.filters.values() if f.slot == slot), None)

    def by_body(self, body: int) -> FilterState | None:
        return next((f for f in self.filters.values() if f.body == body), None)

    def pose(self, filter_id: str) -> tuple[Vec3, Quat]:
        pos, orn = p.getBasePositionAndOrientation(self.filters[filter_id].body, physicsClientId=self._client)
        return tuple(pos), tuple(orn)  # type: ignore[return-value]

    def held(self) -> FilterState | None:
        return next((f for f in self.filters.values() if f.held), None)

    def moving_free(self) -> bool:
        """True while a free filter is still moving (the simulation is not at rest)."""
        for f in self.filters.values():
            if f.slot is None and not f.held:
                lin, ang = p.getBaseVelocity(f.body, physicsClientId=self._client)
                if math.hypot(*lin) > 1e-3 or math.hypot(*ang) > 1e-2:
                    return True
        return False

    # ------------------------------------------------------------------ gripper side

    def grasp(self, filter_id: str, tool_pose: tuple[Vec3, Quat]) -> None:
        """The fingers closed on this filter: from now on it moves with the tool."""
        f = self.filters[filter_id]
        inv_pos, inv_orn = p.invertTransform(*tool_pose)
        f.grasp = p.multiplyTransforms(inv_pos, inv_orn, *self.pose(filter_id))  # type: ignore[assignment]
        f.held = True
        p.resetBaseVelocity(f.body, [0, 0, 0], [0, 0, 0], physicsClientId=self._client)
        LOG.info("grasped %s (seated in %s)", filter_id, f.slot)

    def release(self) -> str:
        """The fingers opened: seat the held filter if it is at an empty, unlocked slot, else free it.

        Returns a sentence saying where the filter ended up.
        """
        f = self.held()
        if f is None:
            return "nothing was held"
        f.held = False
        f.grasp = None
        if f.slot is not None:
            return f"{f.id} stays seated in {f.slot}"
        slot = self._capturing_slot(f)
        if slot is not None:
            f.slot = slot
            self._place(f, *self.slot_poses[slot])
            LOG.info("released %s: seated in %s", f.id, slot)
            return f"{f.id} seated in {slot}"
        p.resetBaseVelocity(f.body, [0, 0, 0], [0, 0, 0], physicsClientId=self._client)
        LOG.info("released %s: free", f.id)
        return f"{f.id} released (free)"

    def follow(self, tool_pose: tuple[Vec3, Quat]) -> None:
        """Move the held filter with the tool.

        Raises:
            SlotBlocked: the move would pull a filter out of a locked slot or push it into one;
                nothing is moved then.
        """
        f = self.held()
        if f is None or f.grasp is None:
            return
        pos, orn = p.multiplyTransforms(*tool_pose, *f.grasp)
        if f.slot is not None:
            seated_pos, _ = self.slot_poses[f.slot]
            if math.dist(pos, seated_pos) > UNSEAT_DISTANCE:
                if self._is_locked(f.slot):
                    raise SlotBlocked(f"filter {f.id} is locked in {f.slot}: it cannot be pulled out (unlock it first)")
                LOG.info("%s pulled out of %s", f.id, f.slot)
                f.slot = None
            else:
                return  # still seated: the rails keep it where it is
        for slot, (slot_pos, slot_orn) in self.slot_poses.items():
            if self._is_locked(slot) and self._in_approach(pos, slot_pos, slot_orn):
                raise SlotBlocked(f"{slot} is locked: its latch blocks inserting filter {f.id} (unlock it first)")
        self._place(f, tuple(pos), tuple(orn))  # type: ignore[arg-type]

    # ------------------------------------------------------------------ every step

    def hold_kinematic(self, tool_pose: tuple[Vec3, Quat]) -> None:
        """Re-place seated and held filters after a physics step (gravity must not move them).

        A held filter goes back to where the grasp puts it relative to the tool, not to where the
        step left it: re-placing it at its own pose would let it sink a little every step.
        """
        for f in self.filters.values():
            if f.slot is not None:
                self._place(f, *self.slot_poses[f.slot])
            elif f.held and f.grasp is not None:
                self._place(f, *p.multiplyTransforms(*tool_pose, *f.grasp))

    # ------------------------------------------------------------------ helpers

    def _place(self, f: FilterState, pos: Vec3, orn: Quat) -> None:
        p.resetBasePositionAndOrientation(f.body, pos, orn, physicsClientId=self._client)
        p.resetBaseVelocity(f.body, [0, 0, 0], [0, 0, 0], physicsClientId=self._client)

    def _relative(self, pos: Vec3, orn: Quat, slot_pos: Vec3, slot_orn: Quat) -> tuple[Vec3, float]:
        inv_pos, inv_orn = p.invertTransform(slot_pos, slot_orn)
        rel_pos, rel_orn = p.multiplyTransforms(inv_pos, inv_orn, pos, orn)
        angle = 2 * math.acos(min(1.0, abs(rel_orn[3])))
        return tuple(rel_pos), angle  # type: ignore[return-value]

    def _in_approach(self, pos: Vec3, slot_pos: Vec3, slot_orn: Quat) -> bool:
        (x, y, z), _ = self._relative(pos, (0, 0, 0, 1), slot_pos, slot_orn)
        return -LATCH_DEPTH < x < LATCH_DEPTH and abs(y) < LATCH_HALF_WIDTH and abs(z) < LATCH_HALF_WIDTH

    def _capturing_slot(self, f: FilterState) -> str | None:
        pos, orn = self.pose(f.id)
        for slot, (slot_pos, slot_orn) in self.slot_poses.items():
            if self.in_slot(slot) is not None or self._is_locked(slot):
                continue
            (x, y, z), angle = self._relative(pos, orn, slot_pos, slot_orn)
            if (
                abs(x) <= CAPTURE_AXIAL
                and abs(y) <= CAPTURE_LATERAL
                and abs(z) <= CAPTURE_LATERAL
                and angle <= CAPTURE_ANGLE
            ):
                return slot
        return None
