"""Debian's Chromium through Playwright, for every suite that drives the console in a browser.

One Chromium of each kind serves a whole pytest worker (:class:`SharedChromium`); each test
module connects to it with a Playwright driver of its own (tests/conftest.py).
:func:`signed_in_pages` opens fresh browser contexts, one per person, and fails the test if any
page raised a script error.
"""

from __future__ import annotations

import logging
import re
import shutil
import subprocess
import tempfile
import threading
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager

from playwright.sync_api import Browser, BrowserContext, Page, Playwright
from playwright.sync_api import Error as PlaywrightError

__all__ = ["CHROMIUM", "CHROMIUM_ARGS", "TIMEOUT_MS", "WEBGL_ARGS", "SharedChromium", "signed_in_pages"]

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
#: Generous, as it bounds a hang, not a speed: other suites share the two cores while these run
#: (under the whole suite, a CI run took over 30 s to answer one start; on a machine half as fast,
#: PAX took 22-28 s over one value set).
TIMEOUT_MS = 120_000
#: What Playwright's own launch adds for tests, for a Chromium started here: no throttling of
#: pages it deems in the background, nothing of a user's profile.
HEADLESS_ARGS = [
    "--headless",
    "--disable-background-timer-throttling",
    "--disable-backgrounding-occluded-windows",
    "--disable-renderer-backgrounding",
    "--disable-ipc-flooding-protection",
    "--disable-hang-monitor",
    "--disable-extensions",
    "--disable-default-apps",
    "--disable-dev-shm-usage",
    "--no-default-browser-check",
    "--password-store=basic",
    "--hide-scrollbars",
    "--mute-audio",
]
#: A connection to the shared Chromium answered within this, or it is replaced.
CONNECT_TIMEOUT_MS = 60_000
log = logging.getLogger(__name__)
_LISTENING = re.compile(r"DevTools listening on (ws://\S+)")


class SharedChromium:
    """One Chromium for every browser test module of a pytest worker, reached over the DevTools
    protocol (``connect_over_cdp``): a launch costs its browser process about a second of CPU, and
    a worker runs a dozen such modules. Each module still has a Playwright driver of its own (see
    tests/conftest.py); the contexts a connection opened end with it. A Chromium that ended, or
    does not answer, is started again.
    """

    def __init__(self, args: Sequence[str]) -> None:
        self.args = list(args)
        self._process: subprocess.Popen[str] | None = None
        self._profile = ""
        self._endpoint = ""
        self._drain: threading.Thread | None = None

    def endpoint(self) -> str:
        """The DevTools WebSocket of the running Chromium, started now if it is not running."""
        if self._process is None or self._process.poll() is not None:
            self._start()
        return self._endpoint

    def connect(self, playwright: Playwright) -> Browser:
        """This Chromium, connected through ``playwright`` (a module's driver). A Chromium that
        does not answer the connection is replaced by a new one, and that is logged: the test
        needs a browser, not that one."""
        try:
            return playwright.chromium.connect_over_cdp(self.endpoint(), timeout=CONNECT_TIMEOUT_MS)
        except PlaywrightError as exc:
            log.warning("the shared Chromium did not answer (%s): starting another", str(exc).splitlines()[0])
            self._start()
            return playwright.chromium.connect_over_cdp(self._endpoint, timeout=CONNECT_TIMEOUT_MS)

    def _start(self) -> None:
        self.close()
        self._profile = tempfile.mkdtemp(prefix="caretaker-chromium-")
        process = subprocess.Popen(
            [CHROMIUM, *HEADLESS_ARGS, *self.args, "--remote-debugging-port=0", f"--user-data-dir={self._profile}"],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            text=True,
        )
        self._process = process
        assert process.stderr is not None
        said: list[str] = []
        for line in process.stderr:  # Chromium says where it listens before anything else can connect
            said.append(line)
            found = _LISTENING.search(line)
            if found:
                self._endpoint = found.group(1)
                break
        else:
            raise RuntimeError(f"Chromium ended before it listened (exit {process.wait()}):\n{''.join(said[-20:])}")
        # the rest of what it says is read and dropped, so a full pipe never blocks it
        self._drain = threading.Thread(target=lambda: [None for _ in process.stderr or ()], daemon=True)
        self._drain.start()

    def close(self) -> None:
        if self._process is not None:
            self._process.terminate()
            try:
                self._process.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self._process.kill()
                self._process.wait()
            if self._drain is not None:
                self._drain.join(timeout=10)  # the pipe ends with the process
            if self._process.stderr is not None:
                self._process.stderr.close()
            self._process = None
        if self._profile:
            shutil.rmtree(self._profile, ignore_errors=True)
            self._profile = ""


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
