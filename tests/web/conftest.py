"""Browser-test fixtures: a real ``caretaker serve`` process and Debian's Chromium via Playwright.

The server runs as its own process, started like any deployment, with the simulated systems of
``simulated_systems.py`` behind the executive (PRIDE_GATEWAY), once on a SQLite ground database
and once on PostgreSQL (the session's server, as the runner role). Each test signs in from fresh
browser contexts, so several "people" can watch one run at once.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, Playwright, expect, sync_playwright

from operator_page import sign_in_on
from web_server import WebServer, new_ground_database, procedure_shelf, start_server

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run"]
#: Generous: other suites share the two cores while these run.
TIMEOUT_MS = 30_000
expect.set_options(timeout=TIMEOUT_MS)


@pytest.fixture(scope="session", params=["sqlite", "postgresql"])
def server(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Iterator[WebServer]:
    """One server on the simulated systems per kind of ground database for the whole suite: a SQLite
    file, and PostgreSQL as the locked-down runner role (test_web_on_real_stack.py has its own)."""
    tmp = tmp_path_factory.mktemp("web")
    postgres = request.getfixturevalue("postgres") if request.param == "postgresql" else None
    served = start_server(tmp, procedure_shelf(tmp), database=new_ground_database(request.param, tmp, postgres))
    yield served
    served.process.stop()


@pytest.fixture(scope="session")
def playwright() -> Iterator[Playwright]:
    """One Playwright driver per session: its sync API cannot run twice at once in a thread."""
    with sync_playwright() as driver:
        yield driver


@pytest.fixture(scope="session")
def browser(playwright: Playwright) -> Iterator[Browser]:
    launched = playwright.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
    yield launched
    launched.close()


@pytest.fixture
def open_page(browser: Browser) -> Iterator:
    """``open_page(server, "alice")`` opens a fresh browser context on that server signed in as that
    user, with their password; script errors on any page fail the test."""
    contexts = []
    script_errors: list[str] = []

    def open_as(on: WebServer, user: str) -> Page:
        context = browser.new_context(viewport={"width": 1500, "height": 1000})
        contexts.append(context)
        page = context.new_page()
        page.on("pageerror", lambda error: script_errors.append(f"{user}: {error}"))
        page.set_default_timeout(TIMEOUT_MS)
        page.goto(on.url)
        sign_in_on(page, user)
        return page

    yield open_as
    for context in contexts:
        context.close()
    assert not script_errors, "the page raised script errors:\n" + "\n".join(script_errors)


@pytest.fixture
def sign_in(open_page, server: WebServer):
    """``sign_in("alice")``: :func:`open_page` on the suite's server."""
    return lambda user: open_page(server, user)
