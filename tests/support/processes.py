"""Test access to the launcher's process handling (python/caretaker/processes.py)."""

from caretaker.processes import ManagedProcess, ProcessFailed, caretaker, python

__all__ = ["COMMAND_HANG_S", "ManagedProcess", "ProcessFailed", "caretaker", "python"]

#: s a command a test runs may take before the test calls it hung: a bound on a hang, not a speed
#: (under a whole suite on a slow machine, commands that take a second alone ran past a minute).
COMMAND_HANG_S = 180.0
