"""Where the procedure-side tests find procedures and SysReps.

The shipped ones are under the repository (``REPO / "procedures"``, ``REPO / "sysrep"``); the
lab bench's, and the broken and hostile procedures the checks must refuse, under
:data:`FIXTURES` (tests/pride/fixtures).
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["FIXTURES", "REPO"]

REPO = Path(__file__).resolve().parents[2]
FIXTURES = REPO / "tests" / "pride" / "fixtures"
