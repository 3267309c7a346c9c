"""Checked reading of Caretaker's data files (YAML and JSON): one mechanism for every loader.

Every file Caretaker reads from a user — scenes, robot configs, AT templates, deployments,
SysReps, bindings — is parsed here into a tree of values that remember their line
(:mod:`datafile.nodes`), then walked by its loader through :class:`Field`, whose checks fail with
one :class:`DataFileError` line: ``file:line: key: problem``. Whatever the input — random bytes,
a YAML bomb, a tag, NaN, a number of ten thousand digits, nesting a million deep — the result is
a value or that one line, never another exception.

A leaf package: it imports nothing of Caretaker, so the procedure side and the robot side can
both use it without importing each other.
"""

from datafile.document import MAX_BYTES, load_file, parse_text, read_text, shipped_or_path
from datafile.errors import DataFileError
from datafile.field import Field
from datafile.nodes import Node

__all__ = ["MAX_BYTES", "DataFileError", "Field", "Node", "load_file", "parse_text", "read_text", "shipped_or_path"]
