"""Browser-test fixtures: a real ``caretaker serve`` process and Debian's Chromium via Playwright.

The server runs as its own process, started like any deployment, with the simulated systems of
``simulated_systems.py`` behind the executive (PRIDE_GATEWAY). Each test signs in from fresh
browser contexts, so several "people" can watch one run at once.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from playwright.sync_api import Browser, Page, Playwright, expect, sync_playwright

from operator_page import sign_in_on
from web_server import WebServer, procedure_shelf, start_server

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run"]
#: Generous: other suites share the two cores while these run.
TIMEOUT_MS = 30_000
expect.set_options(timeout=TIMEOUT_MS)


@pytest.fixture(scope="session")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[WebServer]:
    """One server on the simulated systems for the whole suite (test_web_on_real_stack.py has its own)."""
    tmp = tmp_path_factory.mktemp("web")
    served = start_server(tmp, procedure_shelf(tmp))
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
def sign_in(browser: Browser, server: WebServer) -> Iterator:
    """``sign_in("alice")`` opens a fresh browser context signed in as that user, with their password."""
    contexts = []
    script_errors: list[str] = []

    def open_as(user: str) -> Page:
        context = browser.new_context(viewport={"width": 1500, "height": 1000})
        contexts.append(context)
        page = context.new_page()
        page.on("pageerror", lambda error: script_errors.append(f"{user}: {error}"))
        page.set_default_timeout(TIMEOUT_MS)
        page.goto(server.url)
        sign_in_on(page, user)
        return page

    yield open_as
    for context in contexts:
        context.close()
    assert not script_errors, "the page raised script errors:\n" + "\n".join(script_errors)
