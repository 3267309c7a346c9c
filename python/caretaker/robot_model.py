"""The arm a URDF describes, as ``caretaker new robot`` needs it: its root, its joints and ranges, its tool.

Read with pybullet, as the simulation and the planner will read it, after the project's own URDF
reader has checked the file (a hostile file is one line with its place, never a traceback).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

__all__ = ["Joint", "RobotModel", "ScaffoldError", "read_robot_model"]


class ScaffoldError(Exception):
    """What ``caretaker new`` cannot do with what it was given, and what to give instead."""


@dataclass(frozen=True)
class Joint:
    name: str
    lower: float
    upper: float  # below lower: a continuous joint (pybullet's way of saying it has no range)
    child: str  # the link it moves

    def range_words(self) -> str:
        return "continuous" if self.upper < self.lower else f"[{self.lower:.4f}, {self.upper:.4f}] rad"


@dataclass(frozen=True)
class RobotModel:
    """What a robot folder needs from the URDF: its root, the arm's joints and ranges, its tool."""

    urdf: Path
    base_link: str
    arm: tuple[Joint, ...]  # the moving joints from the root to the tool link, in order
    tool_link: str
    gripper: tuple[Joint, ...]  # the finger joints (open at their upper limit, closed at their lower)

    @property
    def joint_names(self) -> list[str]:
        return [j.name for j in self.arm]


def read_robot_model(urdf: Path, tool_link: str | None, gripper_joints: Sequence[str]) -> RobotModel:
    """The arm of ``urdf`` from its root to ``tool_link`` (default: the deepest link that is not a
    finger), with the joint ranges pybullet reads from it, as the simulation and the planner will.

    Raises:
        DataFileError: the URDF does not parse (file:line).
        ScaffoldError: a tool link or finger joint it does not have, or no moving joint to the tool.
    """
    import pybullet as p

    from datafile.urdf import read_urdf

    read_urdf(urdf)  # hostile input is one line with its place before pybullet sees it
    client = p.connect(p.DIRECT)
    try:
        body = p.loadURDF(str(urdf), useFixedBase=True, physicsClientId=client)
        base_link = p.getBodyInfo(body, physicsClientId=client)[0].decode()
        parent_of: dict[str, tuple[str, Joint | None]] = {}  # link -> (parent link, joint if it moves)
        links = [base_link]
        for index in range(p.getNumJoints(body, physicsClientId=client)):
            info = p.getJointInfo(body, index, physicsClientId=client)
            name, kind, lower, upper, child = info[1].decode(), info[2], info[8], info[9], info[12].decode()
            parent = base_link if info[16] == -1 else links[info[16] + 1]
            links.append(child)
            moving = None if kind == p.JOINT_FIXED else Joint(name, float(lower), float(upper), child)
            parent_of[child] = (parent, moving)
    finally:
        p.disconnect(client)
    joints = {j.name: j for _, j in parent_of.values() if j is not None}
    unknown = [name for name in gripper_joints if name not in joints]
    if unknown:
        raise ScaffoldError(
            f"{urdf.name} has no moving joint {unknown[0]!r}; its moving joints are {', '.join(joints)}"
        )
    gripper = tuple(joints[name] for name in gripper_joints)

    def chain(link: str) -> list[Joint | None]:
        path: list[Joint | None] = []
        while link != base_link:
            link, joint = parent_of[link]
            path.insert(0, joint)
        return path

    fingers = set(gripper)
    if tool_link is None:  # the deepest link whose chain moves no finger
        candidates = [link for link in links if not fingers & set(chain(link))]
        tool_link = max(candidates, key=lambda link: len(chain(link)))
    elif tool_link not in links:
        raise ScaffoldError(f"{urdf.name} has no link {tool_link!r}; its links are {', '.join(links)}")
    path = chain(tool_link)
    if fingers & set(path):
        raise ScaffoldError(f"the tool link {tool_link!r} is moved by a finger joint: name the link the fingers are on")
    arm = tuple(j for j in path if j is not None)
    if not arm:
        raise ScaffoldError(
            f"no joint of {urdf.name} moves {tool_link!r}: give --tool-link, the link that carries the tool"
        )
    return RobotModel(urdf, base_link, arm, tool_link, gripper)
