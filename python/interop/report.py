"""The suite's report: a line per case, a summary table, and ``index.json`` / ``index.html``.

``index.json`` is ``{server: {case: {title, profile, statements, outcome, expected, observed,
duration, frames}}}``, as Autobahn|Testsuite's is per agent; a report directory keeps the servers
earlier runs wrote there, so running once per server builds the matrix of all of them. Everything
in it that came from a server is escaped in the HTML: the server under test is not trusted.
"""

from __future__ import annotations

import html
import json
import logging
from collections.abc import Iterable
from dataclasses import asdict
from pathlib import Path
from typing import Any

from .outcome import CaseResult, Outcome

__all__ = ["case_line", "load_index", "passed", "summary", "to_json", "write_report"]

log = logging.getLogger(__name__)

_COLOURS = {
    "OK": "#8f8",
    "NON-STRICT": "#cf8",
    "INFORMATIONAL": "#ddd",
    "UNIMPLEMENTED": "#fc6",
    "FAILED": "#f66",
}


def case_line(result: CaseResult) -> str:
    """One line for the console: number, outcome, time, title and what was seen."""
    return f"{result.case:<17} {result.outcome.value:<13} {result.duration:6.1f} s  {result.title}: {result.observed}"


def passed(results: Iterable[CaseResult], claimed: Iterable[str]) -> bool:
    """Whether every case of the claimed profiles ended OK, NON-STRICT or INFORMATIONAL."""
    profiles = set(claimed)
    return all(r.outcome.passes for r in results if r.extra.get("profile") in profiles)


def summary(results: list[CaseResult], claimed: Iterable[str]) -> str:
    """A table: per profile, how many cases ended in each outcome, and whether the claim holds."""
    profiles = list(dict.fromkeys(str(r.extra.get("profile")) for r in results))
    claimed_set = set(claimed)
    names = [o.value for o in Outcome]
    rows = [["profile", *names, "verdict"]]
    for profile in profiles:
        mine = [r for r in results if r.extra.get("profile") == profile]
        counts = [str(sum(1 for r in mine if r.outcome.value == name)) for name in names]
        if profile not in claimed_set:
            verdict = "not claimed"
        else:
            verdict = "pass" if all(r.outcome.passes for r in mine) else "FAIL"
        rows.append([profile, *counts, verdict])
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    return "\n".join("  ".join(cell.ljust(width) for cell, width in zip(row, widths, strict=True)) for row in rows)


def _result_dict(result: CaseResult) -> dict[str, Any]:
    return {
        "title": result.title,
        "profile": result.extra.get("profile"),
        "statements": list(result.statements),
        "outcome": result.outcome.value,
        "expected": result.expected,
        "observed": result.observed,
        "duration": result.duration,
        "frames": [asdict(frame) for frame in result.frames],
    }


def to_json(server: str, results: list[CaseResult]) -> dict[str, dict[str, Any]]:
    return {server: {r.case: _result_dict(r) for r in results}}


def load_index(directory: Path) -> dict[str, dict[str, Any]]:
    """The servers an earlier run wrote to ``directory`` (an unreadable file is replaced, with a warning)."""
    path = directory / "index.json"
    if not path.exists():
        return {}
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as error:
        log.warning("%s is unreadable (%s): writing a new one", path, error)
        return {}
    if not isinstance(data, dict) or not all(isinstance(v, dict) for v in data.values()):
        log.warning("%s is not a report of this suite: writing a new one", path)
        return {}
    return data


def write_report(directory: Path, server: str, results: list[CaseResult]) -> Path:
    """Add ``server``'s results to ``directory``'s ``index.json`` and rewrite ``index.html``."""
    directory.mkdir(parents=True, exist_ok=True)
    index = load_index(directory)
    index.update(to_json(server, results))
    (directory / "index.json").write_text(json.dumps(index, indent=1))
    (directory / "index.html").write_text(render_html(index))
    return directory / "index.html"


def _anchor(server_index: int, case: str) -> str:
    return f"s{server_index}-{case.replace('.', '-')}"


def render_html(index: dict[str, dict[str, Any]]) -> str:
    """The matrix (cases × servers, each cell linking to the case's frames), then every case."""
    servers = list(index)
    cases: dict[str, dict[str, Any]] = {}
    for results in index.values():
        for case, result in results.items():
            cases.setdefault(case, result)
    esc = html.escape
    out = [
        "<!doctype html><meta charset='utf-8'><title>rosbridge interop report</title>",
        "<style>body{font-family:sans-serif}td,th{border:1px solid #999;padding:2px 6px}"
        "table{border-collapse:collapse}pre{background:#f4f4f4;padding:6px;white-space:pre-wrap}</style>",
        "<h1>rosbridge v2 interop report</h1>",
        "<p>Statements: docs/interop.md. Outcomes as Autobahn|Testsuite's.</p>",
        "<table><tr><th>case</th><th>title</th><th>statements</th>",
        *(f"<th>{esc(server)}</th>" for server in servers),
        "</tr>",
    ]
    for case, first in cases.items():
        out.append(
            f"<tr><td>{esc(case)}</td><td>{esc(str(first.get('title')))}</td>"
            f"<td>{esc(', '.join(map(str, first.get('statements', []))))}</td>"
        )
        for number, server in enumerate(servers):
            result = index[server].get(case)
            if result is None:
                out.append("<td></td>")
                continue
            outcome = str(result.get("outcome"))
            colour = _COLOURS.get(outcome, "#fff")
            out.append(f"<td style='background:{colour}'><a href='#{_anchor(number, case)}'>{esc(outcome)}</a></td>")
        out.append("</tr>")
    out.append("</table>")
    for number, server in enumerate(servers):
        out.append(f"<h2>{esc(server)}</h2>")
        for case, result in index[server].items():
            frames = "\n".join(
                f"{f.get('at', 0):8.3f} {esc(str(f.get('connection', '')))} "
                f"{'→' if f.get('direction') == 'sent' else '←'} {esc(str(f.get('text', '')))}"
                for f in result.get("frames", [])
            )
            out.append(
                f"<h3 id='{_anchor(number, case)}'>{esc(case)} {esc(str(result.get('title')))}: "
                f"{esc(str(result.get('outcome')))}</h3>"
                f"<p>Statements: {esc(', '.join(map(str, result.get('statements', []))))}. "
                f"Expected: {esc(str(result.get('expected')))}.<br>Observed: {esc(str(result.get('observed')))} "
                f"({result.get('duration')} s)</p><pre>{frames}</pre>"
            )
    return "\n".join(out)
