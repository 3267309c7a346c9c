"""The robot's URDF as the simulation publishes it on ``robot_description`` (latched).

A view draws the robot from this text alone, so a file it names must be findable: a relative
mesh ``filename`` is made an absolute ``file://`` URI on this host, and ``package://`` or other
URIs are left as written (a view across the link resolves those itself or draws the link's
collision primitives). The shipped robots use primitives only and name no files.
"""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["robot_description"]

_FILENAME = re.compile(r'(filename\s*=\s*)(["\'])(.*?)\2')


def robot_description(urdf: Path) -> str:
    """The text of ``urdf`` with every relative ``filename`` made an absolute ``file://`` URI."""
    folder = urdf.resolve().parent

    def absolute(match: re.Match[str]) -> str:
        prefix, quote, name = match.groups()
        if "://" in name:
            return match.group(0)
        path = Path(name) if Path(name).is_absolute() else folder / name
        return f"{prefix}{quote}{path.resolve().as_uri()}{quote}"

    return _FILENAME.sub(absolute, urdf.read_text(encoding="utf-8"))
