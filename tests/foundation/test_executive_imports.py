"""The executive runs without the ground's servers and database libraries.

An onboard executive (on the habitat) has no web server and no ground database: importing
:mod:`pride.executive` must not load starlette, uvicorn, SQLAlchemy, Alembic, psycopg or
Playwright. Measured on a real import (``python -X importtime``, which lists every module loaded),
not read from the source: a module that imports one of them lazily at import time counts too.
"""

from __future__ import annotations

import subprocess
import sys

from caretaker.processes import REPO

GROUND_ONLY = ("starlette", "uvicorn", "sqlalchemy", "alembic", "psycopg", "playwright")


def test_importing_the_executive_loads_no_server_or_database_library() -> None:
    done = subprocess.run(
        [sys.executable, "-X", "importtime", "-c", "import pride.executive"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
    )
    # each line: "import time: self | cumulative | <indent>module"
    loaded = {
        line.rsplit("|", 1)[1].strip().split(".")[0]
        for line in done.stderr.splitlines()
        if line.startswith("import time:") and "|" in line
    }
    assert "pride" in loaded, done.stderr[-2000:]  # the listing is what it claims to be
    assert not loaded & set(GROUND_ONLY), f"pride.executive loads {sorted(loaded & set(GROUND_ONLY))}"
