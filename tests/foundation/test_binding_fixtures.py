"""procedure_language.binding against the shared binding fixtures (tests/fixtures/bindings), which the Java
BindingLoader is tested with too (BindingLoaderTest): both readers accept the same files and
refuse the same ones, each in one line naming the file and what to fix."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from caretaker.processes import REPO
from procedure_language.binding import BindingError, read_binding

FIXTURES = REPO / "tests" / "fixtures" / "bindings"
EXPECTED = yaml.safe_load((FIXTURES / "invalid" / "expected_errors.yaml").read_text())


def _fixtures(kind: str) -> list[Path]:
    return sorted(p for p in (FIXTURES / kind).glob("*.yaml") if p.name != "expected_errors.yaml")


def test_every_invalid_fixture_has_its_expected_error_and_vice_versa() -> None:
    assert {p.name for p in _fixtures("invalid")} == set(EXPECTED)


@pytest.mark.parametrize("path", _fixtures("valid"), ids=lambda p: p.name)
def test_a_valid_fixture_is_read(path: Path) -> None:
    binding = read_binding(path)
    assert binding.robot == "lab" and binding.systems


@pytest.mark.parametrize("path", _fixtures("invalid"), ids=lambda p: p.name)
def test_an_invalid_fixture_is_refused_with_the_shared_message(path: Path) -> None:
    with pytest.raises(BindingError) as refused:
        read_binding(path)
    message = str(refused.value)
    assert "\n" not in message, message
    for part in EXPECTED[path.name]:
        assert part in message, f"{part!r} not in: {message}"


def test_a_link_and_its_bridges_are_read_as_stated() -> None:
    binding = read_binding(FIXTURES / "valid" / "across_a_link.yaml")
    assert (binding.link.one_way_delay, binding.link.outage_budget, binding.link.stated) == (1.3, 60.0, True)
    assert binding.ledger_namespace == "/lab"
    assert {s.rosbridge for s in binding.systems} == {"wss://habitat.example:9090"}
