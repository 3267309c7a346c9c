"""Hostile data files: every loader answers any input with a value or one error line, never a traceback.

For each kind Caretaker reads — scene, robot config, AT template, deployment, SysRep, binding —
hypothesis feeds the loader random bytes and mutations of the shipped file (slices cut or
repeated, bytes replaced, hostile tokens inserted: aliases, tags, NaN, huge numbers, deep
nesting, control characters; or one value anywhere replaced by one of another type).
The contract: the loader returns, or raises
:class:`datafile.DataFileError` whose text is one line naming the file; nothing else, and
within 5 s per input (hypothesis' deadline).
"""

from __future__ import annotations

import json
import re
import subprocess
import sys
import tempfile
from collections.abc import Callable
from datetime import timedelta
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from caretaker.check import KINDS
from datafile import DataFileError
from support.processes import COMMAND_HANG_S

REPO = Path(__file__).resolve().parents[2]

#: kind -> (shipped file, relative paths written in it that must still resolve from a copy elsewhere)
SHIPPED: dict[str, tuple[Path, tuple[str, ...]]] = {
    "scene": (REPO / "sim" / "scenes" / "iva.yaml", ("../robots/",)),
    "robot": (REPO / "python" / "at_ros" / "library" / "robots" / "ur10.yaml", ("../../../../sim/",)),
    "template": (REPO / "python" / "at_ros" / "library" / "templates" / "cdra_filter.json", ()),
    "deployment": (REPO / "deployments" / "iva.yaml", ("../",)),
    "sysrep": (REPO / "sysrep" / "affordance_templates.yaml", ()),
    "binding": (REPO / "sysrep" / "bindings" / "iva.yaml", ("../",)),
}
HOSTILE = [
    "*a",
    "&a [1, 2]",
    "!!python/object/apply:os.system ['true']",
    "!custom x",
    ".nan",
    "-.inf",
    "NaN",
    "Infinity",
    "1e999",
    "9" * 5000,
    "[" * 200,
    "{" * 200,
    "\x00",
    "\x07",
    "\t",
    "\ufeff",
    "\ud800",
    "? [a]\n: b",
    "---\n",
    "<<: *a",
    "~",
    "null",
    "yes",
    "0x1F",
    "1_000",
    "2024-01-01",
    '"\\u0000"',
    "'",
    '"',
    ":",
    "- -",
    "{a: 1, a: 2}",
    "\r\n",
]
FUZZ = settings(
    max_examples=200,
    deadline=timedelta(seconds=5),
    suppress_health_check=[HealthCheck.function_scoped_fixture],
    database=None,
    derandomize=True,
)


def _shipped_text(kind: str) -> str:
    """The shipped file with its relative paths made absolute, so a copy elsewhere still finds them."""
    path, prefixes = SHIPPED[kind]
    text = path.read_text()
    for prefix in prefixes:
        text = text.replace(prefix, f"{(path.parent / prefix).resolve()}/")
    return text


VALUES = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(min_value=-(10**30), max_value=10**30)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=20)
    | st.sampled_from(["open", "closed", "JOINT", "x.urdf", "/tmp", "", "world"]),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=4),
    max_leaves=8,
)


def _paths(data: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Every place in parsed data a value sits (mapping keys and list indices)."""
    out = [prefix]
    if isinstance(data, dict):
        for key, value in data.items():
            out += _paths(value, (*prefix, key))
    elif isinstance(data, list):
        for index, value in enumerate(data):
            out += _paths(value, (*prefix, index))
    return out


def _replaced(data: Any, where: tuple[Any, ...], value: Any) -> Any:
    if not where:
        return value
    copy = dict(data) if isinstance(data, dict) else list(data)
    copy[where[0]] = _replaced(data[where[0]], where[1:], value)  # type: ignore[index]
    return copy


def _value_swaps(text: str, is_json: bool) -> st.SearchStrategy[bytes]:
    """The shipped file with one value (anywhere in it) replaced by another of any type."""
    data = json.loads(text) if is_json else yaml.safe_load(text)
    places = _paths(data)

    def dump(pair: tuple[tuple[Any, ...], Any]) -> bytes:
        changed = _replaced(data, *pair)
        return (json.dumps(changed) if is_json else yaml.safe_dump(changed, allow_unicode=True)).encode(
            "utf-8", "surrogatepass"
        )

    return st.tuples(st.sampled_from(places), VALUES).map(dump)


def _mutations(text: str, is_json: bool) -> st.SearchStrategy[bytes]:
    encoded = text.encode()
    size = len(encoded)
    position = st.integers(0, size)
    cut = st.tuples(position, position).map(lambda ab: encoded[: min(ab)] + encoded[max(ab) :])
    repeat = st.tuples(position, position).map(lambda ab: encoded[: max(ab)] + encoded[min(ab) :])
    insert = st.tuples(position, st.sampled_from(HOSTILE)).map(
        lambda pt: encoded[: pt[0]] + pt[1].encode("utf-8", "surrogatepass") + encoded[pt[0] :]
    )
    replace = st.tuples(position, st.binary(min_size=1, max_size=4)).map(
        lambda pb: encoded[: pb[0]] + pb[1] + encoded[pb[0] + len(pb[1]) :]
    )
    return st.one_of(cut, repeat, insert, replace, st.binary(max_size=2000), _value_swaps(text, is_json))


def _assert_clean(load: Callable[[Path], Any], path: Path, data: bytes) -> None:
    path.write_bytes(data)
    try:
        load(path)
    except DataFileError as exc:
        message = str(exc)
        assert "\n" not in message and "Traceback" not in message
        assert message.startswith(str(path)) or message.startswith(exc.path), message
        assert re.match(r"^.+?(:\d+(:\d+)?)?: \S", message), message


@pytest.mark.parametrize("kind", sorted(SHIPPED))
def test_every_loader_answers_hostile_input_with_one_line(kind: str) -> None:
    load = KINDS[kind][0]
    suffix = ".json" if kind == "template" else ".yaml"
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"fuzzed{suffix}"
        load(Path(SHIPPED[kind][0]))  # the shipped file itself loads

        @FUZZ
        @given(data=_mutations(_shipped_text(kind), kind == "template"))
        def fuzz(data: bytes) -> None:
            _assert_clean(load, path, data)

        fuzz()


@pytest.mark.parametrize(
    ("text", "problem"),
    [
        ("a: &x [1, 2]\nb: *x\n", r":2: YAML aliases \(\*x\) are not allowed"),
        ("a: !!python/object/apply:os.system ['true']\n", r":1: the YAML tag .* is not allowed"),
        ("name: " + "[" * 100, r":1: nested deeper than 64 levels"),
        ("name: x\nname: y\n", r":2: duplicate key 'name'"),
        ("name: " + "9" * 5000 + "\n", r":1: .*is not a usable number"),
        (b"name: \xff\xfe\n", r":1:7: not UTF-8 text"),
    ],
)
def test_hostile_yaml_is_refused_where_it_is_written(tmp_path: Path, text: str | bytes, problem: str) -> None:
    path = tmp_path / "scene.yaml"
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    with pytest.raises(DataFileError, match=problem):
        KINDS["scene"][0](path)


def test_caretaker_check_prints_one_line_per_file_and_no_traceback(tmp_path: Path) -> None:
    files = {
        "bomb.yaml": (
            "a: &a [x, x, x, x, x, x, x, x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\nc: [*b, *b, *b, *b, *b]\n"
        ),
        "nan.json": '{"name": NaN}',
        "random.yaml": bytes(range(256)).decode("latin-1"),
        "deep.json": "[" * 100000,
        "unknown.yaml": "colour: blue\n",
    }
    for name, text in files.items():
        (tmp_path / name).write_text(text, encoding="utf-8")
    shipped = [SHIPPED[kind][0] for kind in sorted(SHIPPED)]
    proc = subprocess.run(
        [sys.executable, "-m", "caretaker.cli", "check", *map(str, shipped), *(str(tmp_path / n) for n in files)],
        capture_output=True,
        text=True,
        timeout=COMMAND_HANG_S,
    )
    assert proc.returncode == 1
    assert "Traceback" not in proc.stdout + proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == len(shipped) + len(files), proc.stdout
    assert all(line.endswith(")") and ": ok (" in line for line in lines[: len(shipped)]), proc.stdout
    by_file = {Path(line.split(":", 1)[0]).name: line for line in lines[len(shipped) :]}
    assert "YAML aliases" in by_file["bomb.yaml"]
    assert "NaN and Infinity are not JSON numbers" in by_file["nan.json"]
    assert "nested deeper than" in by_file["deep.json"]
    assert "cannot tell what kind of file this is" in by_file["unknown.yaml"]
    assert "not valid YAML" in by_file["random.yaml"] or "not UTF-8" in by_file["random.yaml"]
