"""Where a motion starts against where the arm is: the AT server waits for the joint states to
show the arm at a motion's first point before sending it, and otherwise says which joint is off.

In-process on a :class:`ServerCore` (the real stacks' tests run every motion through this check).
"""

from __future__ import annotations

import threading

from at_ros.robot_config import load_robot_configs
from at_ros.server_core import START_TOLERANCE, ServerCore

START = {"shoulder_pan_joint": 0.0, "wrist_1_joint": -1.5}


def _core() -> ServerCore:
    return ServerCore(load_robot_configs()["ur10"], {}, {}, template_folder=None, state_file=None, instances={})


def _hear(core: ServerCore, joints: dict[str, float]) -> None:
    """What the node's joint_states callback does with a message."""
    with core.joints_heard:
        core.inputs.joints.update(joints)
        core.joints_heard.notify_all()


def test_states_from_before_the_last_motion_ended_are_waited_past() -> None:
    core = _core()
    _hear(core, {"shoulder_pan_joint": 0.0, "wrist_1_joint": -0.53})  # still on the way
    feeder = threading.Thread(target=_hear, args=(core, {"wrist_1_joint": -1.5 + START_TOLERANCE / 2}))
    feeder.start()
    assert core.arm_away_from(START, timeout=30.0) is None
    feeder.join()


def test_an_arm_that_stays_elsewhere_is_named_joint_by_joint() -> None:
    core = _core()
    _hear(core, {"shoulder_pan_joint": 0.0, "wrist_1_joint": -0.535})
    assert core.arm_away_from(START, timeout=0.1) == "wrist_1_joint is 0.965 rad (55.3°) from where the motion starts"


def test_a_joint_never_heard_of_is_said_so() -> None:
    core = _core()
    _hear(core, {"shoulder_pan_joint": 0.0})
    assert core.arm_away_from(START, timeout=0.05) == "no joint state of wrist_1_joint was heard"
