"""The AT server's texts in an operator's words: no internal service name reaches an operator.

The AT server and the link to it name the server's ROS services in what they say (``call
plan_command first``, ``/affordance_template_server/execute_command not answered``): a
developer's words. An operator knows the procedure's SysRep commands (``plan_trajectory``,
``execute_plan``), never the services behind them. The Java plugins pass those texts on as
command results; :class:`pride.pax_host.PaxHost`, the procedure side's boundary where every
result from a robot enters, puts them through :func:`operator_words` before anything records or
shows them (the AT server's own log keeps its words).

Known texts become a sentence that says what to do (:data:`KNOWN`); any other mention of one of
the server's services becomes "the AT server's <what> service" (:data:`SERVICES`). The service
names are those of ``at_ros.api.SERVICES``, written out here because the procedure side does not
import the robot side (rclpy).
"""

from __future__ import annotations

import re
from collections.abc import Callable

__all__ = ["KNOWN", "SERVICES", "operator_words"]


def _no_valid_plan(m: re.Match[str]) -> str:
    return f"{m['trajectory']} of {m['instance']} has no valid plan now (the arm was halted or moved): re-plan it first"


def _no_plan_yet(m: re.Match[str]) -> str:
    of = f" of {m['trajectory']}" if m["trajectory"] else ""
    return f"{m['instance']} has no plan{of} yet: plan it first"


#: Texts of the AT server an operator meets, and what they say in an operator's words.
KNOWN: tuple[tuple[re.Pattern[str], Callable[[re.Match[str]], str]], ...] = (
    # execute_plan after a halt, a move of the arm or another plan (at_ros/plan_execute.py)
    (
        re.compile(r"no valid plan for '(?P<trajectory>[^']+)' of (?P<instance>\S+); call plan_command first"),
        _no_valid_plan,
    ),
    # a plan asked for before one was made (at_ros/plan_view.py)
    (
        re.compile(r"(?P<instance>\S+) has no plan(?: of '(?P<trajectory>[^']+)')? yet; call plan_command first"),
        _no_plan_yet,
    ),
)

#: The AT server's services (under its node name), in words.
SERVICES: dict[str, str] = {
    "add_template": "template adding",
    "delete_template": "template removal",
    "get_running": "template list",
    "get_templates": "template library",
    "get_robots": "robot list",
    "plan_command": "planning",
    "execute_command": "execution",
    "set_object_pose": "registration",
    "set_waypoint_pose": "waypoint",
    "get_template_status": "template status",
    "get_status": "status",
    "get_plan": "plan",
    "halt": "halt",
}
#: Bare names that are no word of the procedure's: set_waypoint_pose is also a SysRep command, and
#: halt an operator's word, so only their full names (``/…/affordance_template_server/halt``) go.
_BARE = [name for name in SERVICES if name not in ("set_waypoint_pose", "halt")]
_SERVICE = re.compile(
    r"(?:/?[\w/]*/)?affordance_template_server/(?P<full>" + "|".join(SERVICES) + r")\b"
    r"|\b(?P<bare>" + "|".join(_BARE) + r")\b"
)


def operator_words(text: str) -> str:
    """``text`` with the AT server's known texts said in an operator's words and no service name left."""
    for pattern, words in KNOWN:
        text = pattern.sub(words, text)
    return _SERVICE.sub(lambda m: f"the AT server's {SERVICES[m['full'] or m['bare']]} service", text)
