"""Problems found in a procedure, each pointing at the file position an author must fix."""

from __future__ import annotations

from dataclasses import dataclass

from procedure_language.model import Location

__all__ = ["Problem", "ProcedureError"]


@dataclass(frozen=True, order=True)
class Problem:
    """One error: ``file:line:col: message``, always one line (a message may quote text from the file)."""

    where: Location
    message: str

    def __str__(self) -> str:
        return f"{self.where}: {' '.join(self.message.split())}"


class ProcedureError(ValueError):
    """A procedure cannot be loaded or run; ``problems`` lists every error found."""

    def __init__(self, problems: list[Problem]) -> None:
        self.problems = sorted(problems, key=lambda p: (p.where.path, p.where.line, p.where.col))
        super().__init__("\n".join(str(p) for p in self.problems))
