"""What one case of the suite found: its outcome (as Autobahn|Testsuite names them) and its evidence."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any

__all__ = ["CaseResult", "Frame", "Outcome"]


class Outcome(enum.Enum):
    """A case's verdict. Only OK and NON-STRICT let a claimed profile pass."""

    OK = "OK"
    """Behaves as the statements say."""
    NON_STRICT = "NON-STRICT"
    """Works, but deviates from a SHOULD of the statements."""
    INFORMATIONAL = "INFORMATIONAL"
    """Behaviour recorded, no verdict (the statements leave it open)."""
    UNIMPLEMENTED = "UNIMPLEMENTED"
    """The op was refused as unknown, or answered with a clear "not supported"."""
    FAILED = "FAILED"
    """A wrong answer, no answer within the case's time, a dropped connection or a crash."""

    @property
    def passes(self) -> bool:
        """Whether a profile that claims this case still passes with it."""
        return self in (Outcome.OK, Outcome.NON_STRICT, Outcome.INFORMATIONAL)


@dataclass(frozen=True)
class Frame:
    """One WebSocket message of a case, as it crossed the wire.

    ``direction`` is ``"sent"`` or ``"received"`` (from the suite's side); ``at`` is seconds since
    the case started; ``text`` is the message as text (binary frames as ``"<binary N bytes: hex…>"``);
    ``connection`` names which of the case's connections carried it (a case may open several).
    """

    direction: str
    at: float
    text: str
    connection: str = ""


@dataclass(frozen=True)
class CaseResult:
    """One case's outcome against one peer, with what was expected, what was seen and the frames."""

    case: str  # its number, e.g. "core.3"
    title: str
    statements: tuple[str, ...]  # the numbered statements of docs/interop.md it checks
    outcome: Outcome
    expected: str
    observed: str
    duration: float
    frames: tuple[Frame, ...] = ()
    extra: dict[str, Any] = field(default_factory=dict)
