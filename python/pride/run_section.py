"""A run of part of a procedure: start at a step, stop after one (``caretaker run --from S --to T``).

An operator who did steps 1–3 by hand, or a habitat that must do only step 5 of a long procedure,
runs the rest. What the skipped part would have bound (a record's value, a command's result) is
given instead (``--set``); lint works out what that is (:func:`procedure_language.lint.section_needs`)
and a start that lacks any of it is refused with the list. The section is on the run's record
(RUN_STARTED's ``section``), so a resume, a replay and the report know where the run started.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from procedure_language.lint import CheckedProcedure, section_needs
from procedure_language.model import Procedure, RecordInstruction, Step
from procedure_language.sysrep import check_value

__all__ = ["RunSection", "SectionError"]


class SectionError(ValueError):
    """A section that cannot start: an unknown step, a stop before the start, or values missing."""


@dataclass(frozen=True)
class RunSection:
    """Where a run starts (``start``, a step's id or number), where it stops (``stop``, after that
    step; None: at the procedure's end), and the values the skipped part would have bound
    (``given``: ``name`` or ``result.field`` → value)."""

    start: str
    stop: str | None = None
    given: Mapping[str, Any] = field(default_factory=dict)

    def check(self, checked: CheckedProcedure) -> dict[str, Any]:
        """The variables the run starts with, typed as the procedure declares them.

        Raises:
            SectionError: saying what to fix.
        """
        procedure = checked.procedure
        first, last = self._step(procedure, self.start), self._step(procedure, self.stop) if self.stop else None
        if last is not None and last.number < first.number:
            raise SectionError(
                f"--to {self.stop} is step {last.number}, before --from {self.start} (step {first.number})"
            )
        missing = section_needs(checked, self.start, self.given)
        if missing:
            listed = "; ".join(f"{u.name} (read at {u.where})" for u in missing)
            raise SectionError(
                f"--from {self.start}: the steps it skips would have bound {listed}; "
                f"give {'each' if len(missing) > 1 else 'it'} with --set NAME=VALUE"
            )
        return self.variables(procedure)

    def stops_after(self, procedure: Procedure) -> int | None:
        """The number of the last nominal step the run performs (None: to the procedure's end)."""
        return self._step(procedure, self.stop).number if self.stop else None

    def to_json(self) -> dict[str, Any]:
        return {"from": self.start, "to": self.stop, "given": dict(self.given)}

    @staticmethod
    def from_json(data: Mapping[str, Any]) -> RunSection:
        return RunSection(str(data.get("from", "")), data.get("to"), dict(data.get("given") or {}))

    def variables(self, procedure: Procedure) -> dict[str, Any]:
        """The given values as the run holds them: typed as the procedure declares them, a result's
        values together under the result's name."""
        types = {i.name: i.type for i in procedure.inputs}
        types.update({i.name: i.type for i in procedure.instructions if isinstance(i, RecordInstruction)})
        env: dict[str, Any] = {}
        for name, value in self.given.items():
            base, dot, value_name = name.partition(".")
            try:
                if dot:  # a command result's value: typed by what it reads as (its SysRep gives no type)
                    env.setdefault(base, {})[value_name] = _as_read(value)
                else:
                    env[name] = check_value(name, types.get(name, "string"), value)
            except ValueError as exc:
                raise SectionError(f"--set {name}: {exc}") from None
        return env

    @staticmethod
    def _step(procedure: Procedure, ref: str) -> Step:
        step = procedure.step(ref)
        if step is None:
            raise SectionError(f"no step {ref!r} (steps: {', '.join(s.id for s in procedure.steps)})")
        return step


def _as_read(value: Any) -> Any:
    """A value given as text, read as the number or boolean it spells (else the text)."""
    if not isinstance(value, str):
        return value
    if value in ("true", "false"):
        return value == "true"
    for kind in (int, float):
        try:
            return kind(value)
        except ValueError:
            pass
    return value
