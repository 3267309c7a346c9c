"""What every robot-side process does around its ROS nodes: spin them until stopped, then let go.

The AT server, the planner, the perception node and the command ledger are separate processes
started and stopped by ``caretaker up`` (SIGINT, SIGTERM). Each stops the same way, so the way is
written once here: see :func:`ros_process.lifetime.spinning`. Two more things they share: the
order of commands and halts (:mod:`ros_process.command_order`, the ``issued`` stamps) and the
test-only delay hooks (:mod:`ros_process.delay_hooks`).
"""

from .lifetime import spinning

__all__ = ["spinning"]
