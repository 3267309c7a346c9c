"""An onboard run hosted for the consoles by the ground process that supervises it.

``caretaker run --onboard`` (and ``--attach``) at a terminal, and ``caretaker supervise`` for each
run handed to it, do the same around an :class:`~onboard.downlink.OnboardSupervisor`: publish an
:class:`~console.onboard_view.OnboardView` of the run in the ground database through a
:class:`~console.terminal_host.TerminalHost` (every console shows it live), feed it the events the
ground stores and what it hears of the habitat, and send the operators' actions the consoles
forward up through the supervisor, each waiting as long as the light time makes its answer take.
"""

from __future__ import annotations

import contextlib
import tempfile
from collections.abc import Callable, Iterator, Mapping
from pathlib import Path
from typing import Any

from sqlalchemy.exc import SQLAlchemyError

from console.onboard_view import OnboardView
from console.terminal_host import TerminalHost
from ground.action_requests import OnItsWay
from onboard.downlink import HabitatNews, OnboardSupervisor
from onboard.unit import Unit
from procedure_language.lint import CheckedProcedure, check_procedure
from procedure_language.sysrep import SysRep

__all__ = ["OnboardHosting", "unit_checked"]


class OnboardHosting:
    """The consoles' view of one onboard run, published by ``host`` (None: the consoles do not show
    it; ``say`` is told why when that happens later)."""

    def __init__(
        self, host: TerminalHost | None, unit: Unit, checked: CheckedProcedure, say: Callable[[str], None]
    ) -> None:
        self.host = host
        self._say = say
        self.view = OnboardView(
            unit.run_id,
            checked.procedure,
            binding=unit.binding,
            started_by=unit.user,
            mode=unit.mode,
            sysreps=dict(checked.sysreps),
            host=f"{host.hosting.host if host else 'a runner'} (supervising; the habitat runs it)",
            on_change=(lambda: host.changed(unit.run_id)) if host else None,
        )

    def news(self, news: HabitatNews) -> None:
        """What the ground just heard of the habitat (an :class:`OnboardSupervisor`'s ``on_news``)."""
        self.view.news(
            snapshot=news.snapshot,
            habitat_time=news.habitat_time,
            heard=news.heard,
            waiting=news.waiting,
            silent_since=news.silent_since,
        )

    def hold(self, supervisor: OnboardSupervisor) -> None:
        """Claim the run for the consoles, their actions going up through ``supervisor``.

        Raises:
            HostedElsewhere: another process holds the run (its supervisor).
        """
        if self.host is None:
            return

        def send(action: str, user: str, args: Mapping[str, Any], on_its_way: OnItsWay) -> tuple[str, str]:
            # waits as long as the link's light time makes the answer take (onboard.downlink.ActionTiming)
            outcome = supervisor.act_from_thread(
                action, user, args, lambda timing: on_its_way(timing.expected_at, timing.gives_up_at)
            )
            return outcome.state, outcome.message

        try:
            self.host.host_onboard(self.view, send)
        except SQLAlchemyError as exc:  # the run goes on; the consoles do not show it live
            self._say(f"the onboard run is not shown on the consoles: {exc}")

    def close(self) -> None:
        if self.host is not None:
            self.host.close()


@contextlib.contextmanager
def unit_checked(unit: Unit, sysreps: Mapping[str, SysRep]) -> Iterator[CheckedProcedure]:
    """The unit's procedure, written out as it came (paths checked by :meth:`Unit.from_json`) and
    linted against ``sysreps``, for as long as the ``with`` block supervises its run.

    Raises:
        ProcedureError, SysRepError: it does not lint against them.
    """
    with tempfile.TemporaryDirectory(prefix="caretaker-unit-") as folder:
        for name, text in unit.files.items():
            path = Path(folder) / name
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_text(text, encoding="utf-8")
        yield check_procedure(Path(folder) / unit.procedure, sysreps)
