"""The command line the AT server and the planner share: which robot, which user-owned folders.

``--robot`` names a robot config file, or a ``robot_name`` looked up in the robots folder.
``--library DIR`` is a user's library: templates from ``DIR/templates``, robot configs from
``DIR/robots`` when it has one (a library of templates only is fine; robots then come from
``--robots`` or the shipped library). ``--templates DIR`` and ``--robots DIR`` name either
folder directly. Anything argparse does not know is an error; arguments
for ROS itself go after ``--ros-args``, as for any ROS 2 node.
"""

from __future__ import annotations

import argparse
from dataclasses import dataclass
from pathlib import Path

from at_ros.library import LibraryError, default_library_path
from at_ros.robot_config import RobotConfig, load_robot_config, load_robot_configs

__all__ = ["RobotChoice", "add_robot_options", "choose_robot", "split_ros_args"]


@dataclass(frozen=True)
class RobotChoice:
    robot: RobotConfig
    robots: dict[str, RobotConfig]  # what get_robots lists
    templates: Path


def split_ros_args(argv: list[str]) -> tuple[list[str], list[str]]:
    """``(ours, ros)``: everything from ``--ros-args`` on goes to rclpy, the rest to argparse."""
    if "--ros-args" in argv:
        index = argv.index("--ros-args")
        return argv[:index], argv[index:]
    return argv, []


def add_robot_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--robot",
        required=True,
        metavar="NAME|FILE",
        help="a robot config file, or the robot_name of one in the robots folder",
    )
    parser.add_argument(
        "--library", type=Path, metavar="DIR", help="a library folder: templates/ (and robots/, if it has one)"
    )
    parser.add_argument(
        "--templates", type=Path, metavar="DIR", help="template folder (default: the library's templates/)"
    )
    parser.add_argument(
        "--robots", type=Path, metavar="DIR", help="robot configs folder (default: the library's, else the shipped one)"
    )
    parser.add_argument(
        "--namespace", default="", help="ROS namespace of the robot's topics and services (default: none)"
    )


def choose_robot(args: argparse.Namespace) -> RobotChoice:
    """The robot, the robots folder's configs and the templates folder the options name.

    Raises:
        LibraryError: a folder or file is missing or malformed, or the robot is unknown.
    """
    library: Path = args.library if args.library is not None else default_library_path()
    templates: Path = args.templates or library / "templates"  # the AT server's to load; the planner needs none
    robots_dir: Path | None = args.robots
    if robots_dir is None and args.library is not None and (args.library / "robots").is_dir():
        robots_dir = args.library / "robots"
    robot_path = Path(args.robot)
    if robot_path.suffix in (".yaml", ".yml"):
        robot = load_robot_config(robot_path)
        # A config file alone serves itself; its folder may hold other files (a deployment).
        robots = load_robot_configs(robots_dir) if robots_dir is not None else {}
        robots[robot.robot_name] = robot
        return RobotChoice(robot, robots, templates)
    robots_dir = robots_dir or default_library_path() / "robots"
    robots = load_robot_configs(robots_dir)
    if args.robot not in robots:
        raise LibraryError(
            robots_dir, 0, "", f"unknown robot {args.robot!r}; known: {', '.join(sorted(robots)) or 'none'}"
        )
    return RobotChoice(robots[args.robot], robots, templates)
