"""What goes up, read as hostile: every field checked, each refusal names the field and what to fix."""

from __future__ import annotations

import json
from typing import Any

import pytest

from onboard.unit import OperatorAction, Unit, UnitError, canonical, digest, sign, signed_by

UNIT: dict[str, Any] = {
    "run_id": "lab-1",
    "procedure": "lab/main.xml",
    "files": {"lab/main.xml": "<procedure/>", "lab/sub.xml": "<procedure/>"},
    "binding": "lab.yaml",
    "user": "alice",
    "mode": "autonomous",
    "issued_at": 1_800_000_000.0,
    "expires_at": 1_800_000_300.0,
    "values": {"target": "dock"},
    "confirm_manual": True,
    "confirm_hazardous": False,
    "breakpoints": ["2.1"],
    "version": {"sha256": "ab" * 32, "release": None, "rehearsal": True},
    "approvals": [
        {
            "procedure": "lab/sub.xml",
            "instruction": "1.4",
            "command": "lab.vent",
            "sender": "alice",
            "approver": "bob",
            "approved_at": 1_800_000_000.0,
            "expires_at": 1_800_000_300.0,
        }
    ],
}
APPROVAL = UNIT["approvals"][0]


def test_a_unit_goes_up_and_comes_back_the_same_with_one_hash() -> None:
    unit = Unit.from_json(json.dumps(UNIT))
    assert unit.to_json() == canonical(UNIT)
    assert Unit.from_json(unit.to_json()) == unit
    assert digest(unit.to_json()) == digest(canonical(dict(reversed(list(UNIT.items())))))  # key order is not identity


def test_a_signature_holds_only_for_the_same_text_and_secret() -> None:
    text = canonical(UNIT)
    signature = sign(text, "link secret")
    assert signed_by(text, signature, "link secret")
    assert not signed_by(text, signature, "another secret")
    assert not signed_by(text.replace("dock", "shelf"), signature, "link secret")


@pytest.mark.parametrize(
    ("change", "said"),
    [
        ({"files": {"../etc/passwd": "x"}, "procedure": "../etc/passwd"}, "must be relative, without '..'"),
        ({"files": {"/abs.xml": "x"}, "procedure": "/abs.xml"}, "must be relative"),
        ({"files": {"a.xml": 5}, "procedure": "a.xml"}, "files['a.xml'] must be the file's text, not int"),
        (
            {"procedure": "other.xml"},
            "procedure 'other.xml' is not one of the unit's files (lab/main.xml, lab/sub.xml)",
        ),
        ({"mode": "turbo"}, 'mode must be "autonomous" or "manual"'),
        ({"expires_at": "soon"}, "expires_at must be a time in Unix seconds"),
        ({"expires_at": True}, "expires_at must be a time in Unix seconds"),
        ({"run_id": "a b/c"}, "run_id 'a b/c' must be letters, digits"),
        ({"values": {"target": 3}}, "values must map each record name to its value as text"),
        ({"confirm_manual": "yes"}, "confirm_manual must be true or false, not str"),
        ({"binding": "../ground.yaml"}, "must be relative, without '..'"),
        ({"user": None}, "user must be who uplinked it, not NoneType"),
        (
            {"version": {"sha256": "ab", "release": "3", "rehearsal": False}},
            "version.release must be a release number or null, not '3'",
        ),
        ({"version": {"sha256": "ab", "release": 3}}, "rehearsal is missing: expected true or false"),
        ({"approvals": {"2.1": "bob"}}, "approvals must be a list of approvals, not dict"),
        ({"approvals": ["bob"]}, "approvals[0] must be an object of procedure, instruction"),
        ({"approvals": [{**APPROVAL, "approver": "alice"}]}, "approvals[0]: alice may not approve their own command"),
        (
            {"approvals": [{**APPROVAL, "procedure": "x.xml"}]},
            "approvals[0].procedure 'x.xml' is not one of the unit's",
        ),
        (
            {"approvals": [{**APPROVAL, "expires_at": "later"}]},
            "approvals[0].expires_at must be a time in Unix seconds",
        ),
        ({"approvals": [{**APPROVAL, "instruction": 1.4}]}, "approvals[0].instruction must be an instruction number"),
    ],
)
def test_a_bad_unit_is_refused_with_the_field_and_what_to_fix(change: dict[str, Any], said: str) -> None:
    with pytest.raises(UnitError) as refused:
        Unit.from_json(json.dumps({**UNIT, **change}))
    assert said in str(refused.value)


@pytest.mark.parametrize(
    ("text", "said"),
    [
        ("not json", "the unit is not JSON"),
        ("[1, 2]", "the unit must be a JSON object, not list"),
        (json.dumps({k: v for k, v in UNIT.items() if k != "files"}), "files is missing: expected an object"),
    ],
)
def test_what_is_not_a_unit_at_all_is_refused(text: str, said: str) -> None:
    with pytest.raises(UnitError) as refused:
        Unit.from_json(text)
    assert said in str(refused.value)


def test_an_action_names_a_known_action_with_its_arguments() -> None:
    halt = {
        "key": "k1",
        "run_id": "lab-1",
        "action": "halt",
        "user": "bob",
        "expires_at": 1.9e9,
        "args": {"reason": "x"},
    }
    assert OperatorAction.from_json(json.dumps(halt)).args == {"reason": "x"}
    for change, said in (
        ({"action": "self_destruct"}, "action 'self_destruct' is not one the habitat takes"),
        ({"args": {}}, "action halt needs reason in args"),
        ({"key": ""}, "key must be 1 to 200 characters"),
    ):
        with pytest.raises(UnitError) as refused:
            OperatorAction.from_json(json.dumps({**halt, **change}))
        assert said in str(refused.value)


def test_a_unit_of_part_of_a_procedure_carries_its_section_and_a_whole_one_reads_as_before() -> None:
    part = {**UNIT, "section": {"from": "finish", "to": None}}
    unit = Unit.from_json(json.dumps(part))
    assert unit.section == {"from": "finish", "to": None} and unit.to_json() == canonical(part)
    assert "section" not in json.loads(Unit.from_json(json.dumps(UNIT)).to_json())  # hashed as before
    for bad in ({"from": 3}, {"from": "finish", "to": 4}, {"start": "finish"}, "finish"):
        with pytest.raises(UnitError, match="section"):
            Unit.from_json(json.dumps({**UNIT, "section": bad}))
