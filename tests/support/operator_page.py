"""What the browser tests do on the operator page: start a run, find instructions and audit rows."""

from __future__ import annotations

import atexit
import os
import re
import shutil
import tempfile
from pathlib import Path

from playwright.sync_api import Locator, Page, expect

from support.web_server import PEOPLE

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
#: The IVA procedure's unlock of the dirty filter: hazardous in the cdra SysRep, so under the IVA
#: robot side's critical commanding it is sent only once a second operator approved it.
UNLOCK = "2.4"
#: The console's own approval request, made in a page of the console's origin (it must be the
#: console's origin: the server refuses another site's requests).
_APPROVE = """async ([user, password, runId, number]) => {
    const post = async (path, body, csrf) => {
        const headers = {"Content-Type": "application/json", ...(csrf ? {"X-CSRF-Token": csrf} : {})};
        const response = await fetch(path, {method: "POST", headers, body: JSON.stringify(body)});
        return [response.status, await response.json().catch(() => ({}))];
    };
    const [signed, session] = await post("/api/session", {user, password});
    if (signed !== 200) return `sign-in as ${user}: ${signed} ${session.error}`;
    const [status, answer] = await post(`/api/runs/${encodeURIComponent(runId)}/actions`,
                                        {action: "approve", instruction: number}, session.csrf);
    return status === 200 ? "" : `approve: ${status} ${answer.error}`;
}"""


def start_run(page: Page, procedure: str, mode: str, binding: str = "iva.yaml", *, rehearsal: bool = True) -> str:
    """Start a run from the page's form; returns its run id once the live connection is open.

    A rehearsal by default: the browser tests' procedures are drafts (never released in their
    ground database), and every robot side they use is a simulator."""
    page.select_option("#start-procedure", procedure)
    page.select_option("#start-binding", binding)
    page.check(f"#start-form input[name=mode][value={mode}]")
    page.set_checked("#start-rehearsal", rehearsal)
    before = page.locator("#run-id").inner_text() if page.locator("#run-id").count() else ""
    page.click("#start-button")
    expect(page.locator("#run-id")).not_to_have_text(before or "-")
    expect(page.locator("#run-id")).to_have_text(re.compile("^" + re.escape(procedure.removesuffix(".xml")) + "-"))
    expect(page.locator("#connection")).to_have_attribute("data-state", "open")
    return page.locator("#run-id").inner_text()


def instruction(page: Page, number: str) -> Locator:
    """The instruction numbered as the executive numbers it (``2.6``, ``2.1/1.5``)."""
    return page.locator(f'#procedure li.instruction[data-number="{number}"]')


def expect_current(item: Locator, timeout: float | None = None) -> None:
    """Wait until ``item`` (an instruction) is the run's current one (marked ``current``)."""
    try:
        expect(item).to_have_class(re.compile(r"\bcurrent\b"), timeout=timeout)
    except AssertionError as failure:
        raise _with_where_the_run_is(item.page, failure) from None


def send_for_approval(page: Page, number: str, timeout: float | None = None) -> None:
    """Once the hazardous command ``number`` is current (within ``timeout`` ms, else Playwright's
    wait), the page's operator sends it for a second operator's approval (Send for approval…, Yes),
    and the request is on the record (a new one: a run that came back to it asks again)."""
    item = instruction(page, number)
    expect_current(item, timeout)
    requests = page.locator(f'#audit li[data-kind="approval_requested"][data-instruction="{number}"]')
    asked_before = requests.count()
    item.locator("button.confirm").click()
    page.click("#confirm-yes")
    expect(requests).to_have_count(asked_before + 1)


def approve_as(page: Page, user: str, number: str, password: str | None = None) -> None:
    """``user`` (a test person, or an account whose ``password`` is given), signed in in a browser
    context of their own beside ``page``'s, approves the command ``number`` of ``page``'s run as the
    console's Approve… does: a second operator at another console, without drawing a console."""
    origin = re.match(r"https?://[^/#]+", page.url)
    assert origin is not None, page.url
    browser = page.context.browser
    assert browser is not None, "a page of a persistent context: no browser to open another context in"
    context = browser.new_context()
    try:
        beside = context.new_page()
        beside.goto(f"{origin.group(0)}/api/session")  # a page of the console's origin, its answer unread
        refused = beside.evaluate(
            _APPROVE, [user, PEOPLE[user][2] if password is None else password, page.evaluate("view.runId"), number]
        )
    finally:
        context.close()
    assert not refused, refused


def unlock_approved_by(page: Page, approver: str, password: str | None = None, timeout: float | None = None) -> None:
    """The IVA procedure's unlock, once the run holds there: the page's operator sends it for
    approval and ``approver`` approves it (:func:`approve_as`), so the run goes on."""
    send_for_approval(page, UNLOCK, timeout)
    approve_as(page, approver, UNLOCK, password)


def audit_row(page: Page, kind: str, number: str, actor: str) -> Locator:
    """Entries of the page's audit log for one kind of record, instruction and actor."""
    return page.locator(f'#audit li[data-kind="{kind}"][data-instruction="{number}"][data-actor="{actor}"]')


def where_the_run_is(page: Page, audit_rows: int = 8) -> str:
    """What the page shows of its run, for a failure message: status, the instruction it holds
    at, the hold banner, and the newest audit rows (a failed plan or a verify's timeout shows there)."""
    return page.evaluate(
        """rows => {
            const squash = node => (node?.innerText ?? '').trim().replace(/\\s+/g, ' ');
            const text = selector => squash(document.querySelector(selector));
            const at = document.querySelector('#procedure li.instruction.current');
            const audit = [...document.querySelectorAll('#audit li')].slice(0, rows).map(row => '  ' + squash(row));
            const lost = document.querySelector('#connection').title || 'never lost';
            const link = `connection ${text('#connection')} (${lost})`;
            return [`status ${text('#run-status')}, ${link}, run opened ${view.opening} times`,
                    `at ${at ? at.dataset.number + ': ' + squash(at).slice(0, 200) : 'no instruction'}`,
                    `hold: ${text('#hold')}`, 'newest audit rows:', ...audit].join('\\n');
        }""",
        audit_rows,
    )


def _with_where_the_run_is(page: Page, failure: AssertionError) -> AssertionError:
    """A wait for the run that timed out, with what the page showed then (where it held, why)."""
    return AssertionError(f"{failure}\n--- the page shows:\n{where_the_run_is(page)}")


def shown_image_width(image: Locator) -> int:
    """The natural width of the picture an ``<img>`` shows, once one has loaded.

    Not ``image.decode()``: a live feed replaces ``src`` every few tenths of a second, and a
    decode pending when it does is rejected (EncodingError) though every picture is fine.
    """
    width = image.page.wait_for_function("image => image.complete && image.naturalWidth", arg=image.element_handle())
    return int(width.json_value())


def screenshot(page: Page, name: str) -> None:
    """A picture of the console for the documentation (see IMAGES)."""
    IMAGES.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(IMAGES / name))


def stop_run(page: Page, reason: str) -> None:
    """Stop the open run with a reason, through the Stop dialog."""
    page.click("#stop")
    page.fill("#stop-reason", reason)
    page.click("#stop-yes")
    expect_ended(page, "stopped")


def sign_in_on(page: Page, user: str, password: str | None = None) -> None:
    """Fill the page's sign-in form as ``user`` (with their password unless another is given)."""
    page.fill("#user-id", user)
    page.fill("#password", PEOPLE[user][2] if password is None else password)
    page.click("#sign-in-form button[type=submit]")
    if password is None:
        page.wait_for_selector("#main-view:not([hidden])")


def expect_ended(page: Page, status: str, *, within_ms: float | None = None) -> None:
    """The open run ended as ``status`` (within Playwright's default wait, or ``within_ms`` where
    the robot still moves) and the page shows it as a past run, drawn from the audit log."""
    try:
        expect(page.locator("#run-status")).to_have_text(status, timeout=within_ms)
    except AssertionError as failure:
        raise _with_where_the_run_is(page, failure) from None
    expect(page.locator("#connection")).to_have_text("past run (from the audit log)")
