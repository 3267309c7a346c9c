"""Commands and halts in one order, decided where each arrives on the robot side, by one clock.

A halt must stop every motion whose command reached the robot side before it, wherever that
command still is: waiting in the command ledger, in the AT server between two motions, or on its
way to the robot's controller or gripper. Where two requests meet in one process (the AT server,
the simulation) the order of their arrival there says nothing: a command held up in the ledger
reaches the AT server after a halt it preceded. So each command carries when it reached the
robot side (``issued``, builtin_interfaces/Time: the command ledger stamps it on every request
that has the field), each halt notes when it arrived, and a part about to move the robot refuses
a command issued before a halt it has seen. A request without a stamp (zero: a direct call) was
issued when it arrives.

The clock is the robot side's wall clock: its parts run on one host (several hosts would have to
keep their clocks synchronised). A stamp from the future (another host's clock) counts as now.
"""

from __future__ import annotations

import time
from typing import Any

from builtin_interfaces.msg import Time

__all__ = ["arrived_now", "issued_at", "stamp"]


def arrived_now() -> float:
    """The robot side's clock now, in s: when a command or a halt arrives."""
    return time.time()


def stamp(seconds: float) -> Time:
    """``seconds`` of the robot side's clock as a builtin_interfaces/Time."""
    ns = int(round(seconds * 1e9))
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def issued_at(issued: Any, arrived: float) -> float:
    """When a command was issued: its ``issued`` stamp, or ``arrived`` (when the request arrived)
    for a request without one; never later than ``arrived``."""
    seconds = issued.sec + issued.nanosec * 1e-9
    return arrived if seconds <= 0.0 else min(seconds, arrived)
