"""The link emulator: the ground/habitat boundary as a TCP relay with delay, loss and outages.

``caretaker link`` runs it from the command line (cli.py); tests and benches build a
:class:`LinkEmulator` from a :class:`LinkConfig` or start the command and drive it through
:class:`LinkControl`. The model and its limits are in docs/link.md.
"""

from .control import ControlServer, LinkControl, LinkControlError
from .model import Direction, DirectionConfig, LinkConfig, LinkOptionError, Outage, OutageKind
from .relay import LinkEmulator
from .stats import ConnectionStats, LinkStats
from .tcp_model import SegmentFate, TcpModel

__all__ = [
    "ConnectionStats",
    "ControlServer",
    "Direction",
    "DirectionConfig",
    "LinkConfig",
    "LinkControl",
    "LinkControlError",
    "LinkEmulator",
    "LinkOptionError",
    "LinkStats",
    "Outage",
    "OutageKind",
    "SegmentFate",
    "TcpModel",
]
