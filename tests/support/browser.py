"""Debian's Chromium through Playwright, for every suite that drives the console in a browser.

One Playwright driver serves the whole test session (tests/conftest.py): its sync API cannot run
twice at once in a thread. :func:`signed_in_pages` opens fresh browser contexts, one per person,
and fails the test if any page raised a script error.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager

from playwright.sync_api import Browser, BrowserContext, Page

__all__ = ["CHROMIUM", "CHROMIUM_ARGS", "TIMEOUT_MS", "WEBGL_ARGS", "signed_in_pages"]

CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
#: WebGL 2 without a GPU, for the 3D view: ANGLE on SwiftShader draws the WebGL canvas, and the page
#: is composited in software, as Chromium does on a machine without a usable GPU. Without
#: ``--disable-gpu-compositing`` SwiftShader would also composite the whole page, redrawing every
#: pixel of the 1500x1000 console for each frame of the view (79 ms a frame on these machines,
#: docs/benchmarks.md "3D view frame rate"); software compositing redraws only what changed.
WEBGL_ARGS = [
    "--no-sandbox",
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--disable-gpu-compositing",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--no-first-run",
]
#: Generous: other suites share the two cores while these run.
TIMEOUT_MS = 30_000


@contextmanager
def signed_in_pages(browser: Browser, sign_in_on: Callable[[Page, str], None]) -> Iterator[Callable[[str, str], Page]]:
    """``open_as(url, user)``: a page of a fresh context at ``url``, signed in as ``user`` by ``sign_in_on``."""
    contexts: list[BrowserContext] = []
    script_errors: list[str] = []

    def open_as(url: str, user: str) -> Page:
        context = browser.new_context(viewport={"width": 1500, "height": 1000})
        contexts.append(context)
        page = context.new_page()
        page.on("pageerror", lambda error: script_errors.append(f"{user}: {error}"))
        page.set_default_timeout(TIMEOUT_MS)
        page.goto(url)
        sign_in_on(page, user)
        return page

    try:
        yield open_as
    except BaseException as failure:  # a script error may be why the test failed: say so with its failure
        if script_errors:
            failure.add_note("the page raised script errors:\n" + "\n".join(script_errors))
        raise
    finally:
        for context in contexts:
            context.close()
    assert not script_errors, "the page raised script errors:\n" + "\n".join(script_errors)
