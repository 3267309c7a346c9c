"""A static site for the 3D view's browser tests: the built bundle, a test page and documents.

A real HTTP server on 127.0.0.1 (Python's, in a thread), so Chromium loads the bundle and the
documents the way it would from ``caretaker serve``.
"""

from __future__ import annotations

import json
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent
REPO = HERE.parents[1]
BUNDLE = REPO / "python" / "console" / "static" / "spatial.js"
PAGE = HERE / "spatial_test_page.html"


class SpatialSite:
    """Served files by path; ``put_json`` adds a document while the server runs."""

    def __init__(self) -> None:
        self.files: dict[str, tuple[bytes, str]] = {
            "/": (PAGE.read_bytes(), "text/html; charset=utf-8"),
            "/spatial.js": (BUNDLE.read_bytes(), "text/javascript; charset=utf-8"),
        }
        self.url = ""

    def put_json(self, path: str, data: Any) -> str:
        self.files[path] = (json.dumps(data).encode(), "application/json")
        return path


@contextmanager
def serve_site() -> Iterator[SpatialSite]:
    if not BUNDLE.exists():
        raise FileNotFoundError(f"{BUNDLE} is missing: `make setup` builds it (tools/setup.sh, step 'spatial')")
    site = SpatialSite()

    class Handler(BaseHTTPRequestHandler):
        def do_GET(self) -> None:
            body, kind = site.files.get(self.path.split("?")[0], (b"not found", "text/plain"))
            self.send_response(200 if kind != "text/plain" else 404)
            self.send_header("Content-Type", kind)
            self.send_header("Content-Length", str(len(body)))
            self.end_headers()
            self.wfile.write(body)

        def log_message(self, format: str, *args: Any) -> None:
            pass

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    site.url = f"http://127.0.0.1:{server.server_address[1]}"
    thread = threading.Thread(target=server.serve_forever, name="spatial-site", daemon=True)
    thread.start()
    try:
        yield site
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)
