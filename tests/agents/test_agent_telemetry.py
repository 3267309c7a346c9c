"""How an agent sees telemetry: a value placed against its limits, in the answer's words, and the
procedure that answers an item out of its limits found among the listed ones. (An agent reading
the real IVA robot's telemetry through ``caretaker agent``: tests/web/test_web_on_real_stack.py.)"""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from agent.agent_desk import ProcedureFacts, TelemetryFacts
from agent.answers import procedure_entry, telemetry_entry
from pride.run_setup import load_sysreps
from procedure_language.lint import check_procedure
from support.procedures import REPO

CARETAKER = Path(sys.executable).with_name("caretaker")
SYSREPS = load_sysreps([REPO / "sysrep"])
CO2 = next(item for item in SYSREPS["cdra"].telemetry if item.id == "co2_partial_pressure")


@pytest.mark.parametrize(
    ("value", "state", "limit"),
    [(2.5, "green", None), (4.4, "yellow", "yellow above 4"), (5.6, "red", "red above 5.3"), (None, "no value", None)],
)
def test_a_value_is_placed_against_its_limits(value: float | None, state: str, limit: str | None) -> None:
    entry = telemetry_entry(TelemetryFacts("cdra", CO2, value, None if value is None else 0.4, stale=False))
    assert (entry.state, entry.limit, entry.units) == (state, limit, "mmHg")


def test_the_procedure_that_answers_an_item_out_of_limits_says_so_in_its_listing() -> None:
    high = telemetry_entry(TelemetryFacts("cdra", CO2, 4.4, 0.4, stale=False))  # yellow, as read_telemetry says
    answering = {}
    for name in ("iva_cdra_filter_replacement.xml", "eva_inspection.xml"):
        checked = check_procedure(REPO / "procedures" / name, SYSREPS)
        entry = procedure_entry(ProcedureFacts(name, checked, "0" * 64, 1, "bob"))  # as list_procedures lists it
        answering[name] = [(r.state, r.text) for r in entry.responds_to if (r.system, r.item) == ("cdra", high.item)]
    assert answering["eva_inspection.xml"] == []
    [(state, text)] = answering["iva_cdra_filter_replacement.xml"]
    assert state == "yellow" == high.state  # yellow or worse: this reading calls for it
    assert "the filter locked in the CDRA cabinet is saturated" in text
