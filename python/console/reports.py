"""After-action reports for the past-runs list: written by pride's report module on request.

The web view does not render reports itself; it asks :func:`pride.report.write_report` (what
``caretaker report RUN`` uses) for the HTML file and serves it, so the page and the terminal
give the same report, in the same words (the SysRep labels of the console's catalog).
"""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from pathlib import Path

from pride.phrasing import Wording
from records.audit_log import AuditLog

__all__ = ["report_writer"]


def report_writer(audit_log: AuditLog, out_dir: Path) -> Callable[[str, Wording], Path] | None:
    """A function writing a run's HTML report in the given wording and returning its path; None
    without pride.report."""
    if importlib.util.find_spec("pride.report") is None:
        return None

    def write(run_id: str, wording: Wording) -> Path:
        from pride.report import write_report

        html_path, _markdown_path = write_report(audit_log.events(run_id), out_dir, wording=wording)
        return Path(html_path)

    return write
