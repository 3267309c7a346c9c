"""A request refused by a named rule: what the agent record stores of every refusal.

The rule is what a reader of the record (or a test) matches on; the message is for the one who
asked, and says what to fix. Each part that refuses has its own subclass, so a caller catches
only the refusals of the part it called.
"""

from __future__ import annotations

__all__ = ["Refused"]


class Refused(Exception):
    """A request a rule does not allow: ``rule`` names the rule, ``message`` says why."""

    def __init__(self, rule: str, message: str) -> None:
        super().__init__(message)
        self.rule = rule
        self.message = message
