"""A second operator for the unattended runs of the tests: the IVA procedure's unlock is hazardous
(the cdra SysRep), so under the IVA robot side's critical commanding ``caretaker run`` sends it
only with a second operator's approval, given on its command line (``--approver``, checked
against that operator's account in the run's ground database)."""

from __future__ import annotations

from collections.abc import Mapping

from pride.approvals import APPROVER_PASSWORD_ENV
from support.web_server import PEOPLE, add_people

__all__ = ["APPROVED_BY_BOB", "approver_env"]

#: ``caretaker run`` options of an unattended run: its user sends each hazardous command for
#: approval, and bob, a second operator, approves it.
APPROVED_BY_BOB = ("--confirm-hazardous", "--approver", "bob")


def approver_env(db_url: str, env: Mapping[str, str]) -> dict[str, str]:
    """``env`` for an unattended run on the new ground database ``db_url`` with
    :data:`APPROVED_BY_BOB`: the test people's accounts added to it, bob's password where the
    runner reads it (never on a command line)."""
    add_people(db_url)
    return {**env, APPROVER_PASSWORD_ENV: PEOPLE["bob"][2]}
