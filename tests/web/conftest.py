"""Browser-test fixtures: a real ``caretaker serve`` process and Debian's Chromium via Playwright.

The server runs as its own process, started like any deployment, with the simulated systems of
``simulated_systems.py`` behind the executive (PRIDE_GATEWAY), once on a SQLite ground database
and once on PostgreSQL (the session's server, as the runner role). Each test signs in from fresh
browser contexts, so several "people" can watch one run at once.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator

import pytest
from playwright.sync_api import Browser, Page, Playwright, expect

from support.browser import TIMEOUT_MS, SharedChromium, signed_in_pages
from support.operator_page import sign_in_on
from support.web_server import WebServer, new_ground_database, procedure_shelf, start_server

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


@pytest.fixture(scope="module")
def webgl_browser(playwright: Playwright, chromium: dict[str, SharedChromium]) -> Iterator[Browser]:
    """Chromium with WebGL on SwiftShader, for the 3D view's suites (this worker's, as ``browser``)."""
    yield chromium["webgl"].connect(playwright)


@pytest.fixture
def open_page(browser: Browser) -> Iterator[Callable[[WebServer, str], Page]]:
    """``open_page(server, "alice")`` opens a fresh browser context on that server signed in as that
    user, with their password; script errors on any page fail the test."""
    with signed_in_pages(browser, sign_in_on) as open_as:
        yield lambda on, user: open_as(on.url, user)


@pytest.fixture
def sign_in(open_page: Callable[[WebServer, str], Page], server: WebServer) -> Callable[[str], Page]:
    """``sign_in("alice")``: :func:`open_page` on the suite's server."""
    return lambda user: open_page(server, user)
