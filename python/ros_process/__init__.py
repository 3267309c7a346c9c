"""What every robot-side process does around its ROS nodes: spin them until stopped, then let go.

The AT server, the planner, the perception node and the command ledger are separate processes
started and stopped by ``caretaker up`` (SIGINT, SIGTERM). Each stops the same way, so the way is
written once here: see :func:`ros_process.lifetime.spinning`.
"""

from .lifetime import spinning

__all__ = ["spinning"]
