"""The one error every data-file loader raises: which file, which line, which key, what is wrong."""

from __future__ import annotations

from pathlib import Path

__all__ = ["DataFileError"]


class DataFileError(ValueError):
    """A data file that cannot be used. ``str(err)`` is one line: ``file:line: key: problem``.

    ``line`` is 1-based; 0 means the problem is the file as a whole (unreadable, too large).
    ``column`` (1-based, optional) is given for syntax errors: ``file:line:column: problem``.
    ``key`` is the path of the offending entry (``robot.gripper.poses.open``,
    ``display_objects[0].shape``), empty for the file or its top level.
    """

    def __init__(self, path: str | Path, line: int, key: str, problem: str, *, column: int = 0) -> None:
        self.path = str(path)
        self.line = line
        self.column = column
        self.key = key
        self.problem = problem
        location = f"{self.path}:{line}" if line else self.path
        if line and column:
            location += f":{column}"
        # One line, always: a problem quoting the file's text must not break it.
        text = f"{location}: {key}: {problem}" if key else f"{location}: {problem}"
        super().__init__(" ".join(text.split("\n")))
