"""What the browser tests do on the operator page: start a run, find instructions and audit rows."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

from playwright.sync_api import Locator, Page, expect

REPO = Path(__file__).resolve().parents[2]
#: Where the browser tests save their screenshots. ``make docs`` sets CARETAKER_SCREENSHOTS to
#: docs/images to refresh the pictures of the README; otherwise they go to a temporary folder,
#: so a test run never writes a tracked file.
SCREENSHOTS_ENV = "CARETAKER_SCREENSHOTS"
if os.environ.get(SCREENSHOTS_ENV):
    IMAGES = Path(os.environ[SCREENSHOTS_ENV])
else:
    IMAGES = Path(tempfile.mkdtemp(prefix="caretaker-screenshots-"))
    atexit.register(shutil.rmtree, IMAGES, True)
IVA = "iva_cdra_filter_replacement.xml"


def start_run(page: Page, procedure: str, mode: str, binding: str = "iva.yaml") -> str:
    """Start a run from the page's form; returns its run id once the live connection is open."""
    page.select_option("#start-procedure", procedure)
    page.select_option("#start-binding", binding)
    page.check(f"#start-form input[name=mode][value={mode}]")
    page.click("#start-button")
    expect(page.locator("#connection")).to_have_attribute("data-state", "open")
    run_id = page.locator("#run-id").inner_text()
    assert run_id.startswith(procedure.removesuffix(".xml"))
    return run_id


def instruction(page: Page, number: str) -> Locator:
    """The instruction numbered as the executive numbers it (``2.6``, ``2.1/1.5``)."""
    return page.locator(f'#procedure li.instruction[data-number="{number}"]')


def audit_row(page: Page, kind: str, number: str, actor: str) -> Locator:
    """Rows of the page's audit log for one kind of record, instruction and actor."""
    return page.locator(f'#audit tbody tr[data-kind="{kind}"][data-instruction="{number}"][data-actor="{actor}"]')
