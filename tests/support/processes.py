"""Test access to the launcher's process handling (python/caretaker/processes.py)."""

from caretaker.processes import ManagedProcess, ProcessFailed, caretaker, python

__all__ = ["ManagedProcess", "ProcessFailed", "caretaker", "python"]
