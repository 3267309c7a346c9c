"""ROS names a client may use: topics, services and actions, checked before rclpy sees them.

rclpy raises (with rcl's source file and line in the text) on a name it cannot use, and a name
with characters UTF-8 cannot carry fails even earlier; so every name from a client is checked
here and refused with an answer saying what a valid name looks like.  Relative names
(``chatter``) are taken as absolute (``/chatter``), as rosbridge does.
"""

from __future__ import annotations

import re
from functools import lru_cache

from rclpy.exceptions import InvalidServiceNameException, InvalidTopicNameException
from rclpy.validate_full_topic_name import validate_full_topic_name

from .protocol import InvalidName, client_text

_ABSOLUTE = re.compile(r"(?:/[A-Za-z_][A-Za-z0-9_]*)+\Z")
_ACTION_SUFFIX = "/_action/feedback"
"""The longest name ROS derives from an action's name; it must be valid too."""


@lru_cache(maxsize=4096)  # valid names only: a refusal raises, which is not cached
def ros_name(kind: str, value: str) -> str:
    """The absolute ROS name of ``value`` for ``kind`` (topic, service or action).

    Raises:
        InvalidName: not a valid ROS name (the text says what a valid one looks like).
    """
    name = value if value.startswith("/") else "/" + value
    if not _ABSOLUTE.match(name):
        raise InvalidName(
            f"{kind} name {client_text(value, 80)!r} is not a valid ROS name: expected tokens of "
            f"letters, digits and '_' (not starting with a digit) joined by '/', like /robot/joint_states"
        )
    try:
        validate_full_topic_name(name + _ACTION_SUFFIX if kind == "action" else name, is_service=kind == "service")
    except (InvalidTopicNameException, InvalidServiceNameException):
        raise InvalidName(
            f"{kind} name {client_text(value, 80)!r} is too long for ROS ({len(name)} characters)"
        ) from None
    return name
