"""Every case of the suite, by profile, in the order they run."""

from __future__ import annotations

from . import cases_at, cases_core, cases_errors, cases_fragments, cases_link, cases_services, cases_websocket
from .runner import Case

__all__ = ["ALL_CASES", "DEFAULT_PROFILES", "PROFILES", "cases_of"]

ALL_CASES: tuple[Case, ...] = (
    *cases_core.CASES,
    *cases_services.CASES,
    *cases_fragments.CASES,
    *cases_errors.CASES,
    *cases_websocket.CASES,
    *cases_at.CASES,
    *cases_link.again_over_the_link(c for c in (*cases_core.CASES, *cases_services.CASES) if c.profile != "actions"),
    cases_link.quiet_case(),
)

PROFILES: tuple[str, ...] = tuple(dict.fromkeys(case.profile for case in ALL_CASES))
"""Profile names in the order their cases run."""

DEFAULT_PROFILES: tuple[str, ...] = tuple(p for p in PROFILES if p not in ("auth", "at", "link"))
"""What a server is checked for unless it names its profiles (``auth`` needs a secret, ``at`` an
Affordance Template server behind the bridge, ``link`` a link between the suite and the server)."""


def cases_of(profiles: tuple[str, ...]) -> list[Case]:
    """The cases of these profiles, in the suite's order."""
    return [case for case in ALL_CASES if case.profile in profiles]
