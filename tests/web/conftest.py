"""Browser-test fixtures: a real ``caretaker serve`` process and Debian's Chromium via Playwright.

The server runs as its own process, started like any deployment, with the simulated systems of
``simulated_systems.py`` behind the executive (PRIDE_GATEWAY). Each test signs in from fresh
browser contexts, so several "people" can watch one run at once.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, expect, sync_playwright

from support.processes import ManagedProcess, caretaker

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking", "--disable-component-update",
                 "--disable-sync", "--no-first-run"]
#: Generous: other suites share the two cores while these run.
TIMEOUT_MS = 30_000
expect.set_options(timeout=TIMEOUT_MS)


class WebServer:
    """A running ``caretaker serve`` and where it listens."""

    def __init__(self, process: ManagedProcess, url: str, db: Path) -> None:
        self.process = process
        self.url = url
        self.db = db


def _ready_url(process: ManagedProcess) -> str:
    line = next(line for line in process.output if line.startswith("READY serve "))
    return line.split()[-1]


def start_server(tmp: Path, procedures: Path, *extra: str) -> WebServer:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(HERE), env.get("PYTHONPATH", "")]))
    env["PRIDE_GATEWAY"] = "simulated_systems:open_simulated_systems"
    env["SIMULATED_MOTION_S"] = "0.6"
    db = tmp / "audit.db"
    process = caretaker(
        "serve", "--port", "0", "--db", f"sqlite:///{db}", "--procedures", str(procedures),
        "--reports", str(tmp / "reports"), "--camera", "ee_camera", "--camera-period", "0.1", *extra,
        env=env, name="serve",
    )
    try:
        process.wait_ready(60)
    except Exception:
        process.stop()
        raise
    return WebServer(process, _ready_url(process), db)


def procedure_shelf(tmp: Path) -> Path:
    """The shipped procedures plus this suite's walk-through, in one directory the server lists."""
    shelf = tmp / "procedures"
    shelf.mkdir()
    for source in [*sorted((REPO / "procedures").glob("*.xml")), *sorted((HERE / "fixtures" / "procedures").glob("*.xml"))]:
        (shelf / source.name).symlink_to(source)
    return shelf


@pytest.fixture(scope="module")
def server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[WebServer]:
    tmp = tmp_path_factory.mktemp("web")
    served = start_server(tmp, procedure_shelf(tmp))
    yield served
    served.process.stop()


@pytest.fixture(scope="session")
def browser() -> Iterator[Browser]:
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=CHROMIUM, headless=True, args=CHROMIUM_ARGS)
        yield launched
        launched.close()


@pytest.fixture
def sign_in(browser: Browser, server: WebServer) -> Iterator:
    """``sign_in("alice")`` opens a fresh browser context signed in as that user."""
    contexts = []
    script_errors: list[str] = []

    def open_as(user: str) -> Page:
        context = browser.new_context(viewport={"width": 1500, "height": 1000})
        contexts.append(context)
        page = context.new_page()
        page.on("pageerror", lambda error: script_errors.append(f"{user}: {error}"))
        page.set_default_timeout(TIMEOUT_MS)
        page.goto(server.url)
        page.fill("#user-id", user)
        page.click("#sign-in-form button[type=submit]")
        page.wait_for_selector("#main-view:not([hidden])")
        return page

    yield open_as
    for context in contexts:
        context.close()
    assert not script_errors, "the page raised script errors:\n" + "\n".join(script_errors)
