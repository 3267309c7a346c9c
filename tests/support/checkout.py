"""The checkout as git sees it: what a test that runs a user's folder must leave unchanged."""

from __future__ import annotations

import subprocess

from caretaker.processes import REPO

__all__ = ["checkout_status"]


def checkout_status() -> str:
    """``git status --porcelain --untracked-files=all`` of the checkout: every file changed or added."""
    return subprocess.run(
        ["git", "-C", str(REPO), "status", "--porcelain", "--untracked-files=all"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
