"""Which run controls which robot, decided in the ground database so every console and runner agrees.

One row per controlled robot in ``robot_control`` (revision 0003 of :mod:`records.migrations`), in
the audit log's database: ``robot`` (the binding's ``robot:``, primary key), ``run_id``,
``user_id``, ``since``, ``reason``. Every change is one atomic statement, so two processes can
never both hold a robot:

- :meth:`RobotControl.acquire` INSERTs the row; the primary key refuses a second one, and the
  refusal names who holds the robot. The run that holds it may acquire it again (a resume).
- :meth:`RobotControl.take_over` replaces the holder with an UPDATE that names the holder it
  replaces (compare and swap): two takeovers at once cannot both win.
- :meth:`RobotControl.release` DELETEs the row only while it is still this run's.

A runner that died leaves its row: the robot stays controlled by that run until it is resumed
(and finishes) or an operator takes over with a reason. Like the audit log, every call waits out
a database outage (up to ``outage_budget`` seconds) before it raises.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from typing import TypeVar

from sqlalchemy import (
    Column,
    DateTime,
    MetaData,
    String,
    Table,
    Text,
    create_engine,
    delete,
    insert,
    make_url,
    select,
    update,
)
from sqlalchemy.engine import Engine
from sqlalchemy.exc import IntegrityError, InterfaceError, OperationalError

from pride.run_control import RobotControlled
from pride.states import Controller, OperatorActionError
from records.audit_chain import utc
from records.audit_log import DEFAULT_OUTAGE_BUDGET, SQLITE_BUSY_TIMEOUT_S, AuditLogUnavailable, database_url

__all__ = ["TABLE", "RobotControl", "robot_control"]

log = logging.getLogger(__name__)

#: The table's name in the ground database.
TABLE = "robot_control"
_FIRST_RETRY = 0.05
_LONGEST_RETRY = 2.0
_T = TypeVar("_T")

#: The table at the newest revision (migration 0003 creates it).
robot_control = Table(
    TABLE,
    MetaData(),
    Column("robot", String(120), primary_key=True),
    Column("run_id", String(120), nullable=False),
    Column("user_id", String(120), nullable=False),
    Column("since", DateTime(timezone=True), nullable=False),
    Column("reason", Text, nullable=False),
)
_C = robot_control.c


class RobotControl:
    """Control of robots in the database at ``url`` (the audit log's): the ground's
    :class:`~pride.run_control.ControlStore`. Thread-safe."""

    def __init__(self, url: str, *, outage_budget: float = DEFAULT_OUTAGE_BUDGET) -> None:
        self.url = url
        self.location = make_url(database_url(url)).render_as_string(hide_password=True)  # for messages
        self.outage_budget = outage_budget
        sqlite = url.startswith("sqlite")
        options: dict[str, object] = {"timeout": SQLITE_BUSY_TIMEOUT_S} if sqlite else {"connect_timeout": 5}
        self._engine: Engine = create_engine(database_url(url), connect_args=options)
        self._closed = threading.Event()

    def holder(self, robot: str) -> Controller | None:
        """Who controls ``robot`` now (None: nobody)."""
        return self._retrying(lambda: self._holder(robot))

    def holds(self, robot: str, run_id: str) -> bool:
        """Whether ``run_id`` controls ``robot`` now."""
        holder = self.holder(robot)
        return holder is not None and holder.run_id == run_id

    def acquire(self, robot: str, run_id: str, user: str) -> Controller:
        """Take control of ``robot`` for ``run_id``, or raise :class:`RobotControlled` naming the holder."""

        def attempt() -> Controller:
            while True:
                now = datetime.now(UTC)
                try:
                    with self._engine.begin() as connection:
                        connection.execute(
                            insert(robot_control).values(robot=robot, run_id=run_id, user_id=user, since=now, reason="")
                        )
                    return Controller(robot, run_id, user, now)
                except IntegrityError:
                    holder = self._holder(robot)
                if holder is None:
                    continue  # released between the INSERT and the read: try again
                if holder.run_id != run_id:
                    raise RobotControlled(holder)
                with self._engine.begin() as connection:  # this run again (a resume): now this user's
                    connection.execute(
                        update(robot_control).where(_C.robot == robot, _C.run_id == run_id).values(user_id=user)
                    )
                return Controller(robot, run_id, user, holder.since, holder.reason)

        return self._retrying(attempt)

    def take_over(self, robot: str, run_id: str, user: str, reason: str) -> Controller | None:
        """Take control of ``robot`` for ``run_id`` from whoever holds it; returns the previous holder."""
        if not reason.strip():
            raise OperatorActionError("say why you take control of the robot from the run that holds it")

        def attempt() -> Controller | None:
            while True:
                holder = self._holder(robot)
                now = datetime.now(UTC)
                values = {"run_id": run_id, "user_id": user, "since": now, "reason": reason}
                if holder is None:
                    try:
                        with self._engine.begin() as connection:
                            connection.execute(insert(robot_control).values(robot=robot, **values))
                        return None
                    except IntegrityError:
                        continue  # someone acquired it meanwhile: take it from them
                with self._engine.begin() as connection:  # only from the holder just read (compare and swap)
                    swapped = connection.execute(
                        update(robot_control).where(_C.robot == robot, _C.run_id == holder.run_id).values(**values)
                    ).rowcount
                if swapped == 1:
                    return holder

        return self._retrying(attempt)

    def release(self, robot: str, run_id: str) -> None:
        """Give up ``robot`` if ``run_id`` still holds it (a run taken over releases nothing)."""

        def attempt() -> None:
            with self._engine.begin() as connection:
                connection.execute(delete(robot_control).where(_C.robot == robot, _C.run_id == run_id))

        self._retrying(attempt)

    def close(self) -> None:
        """Release the connections; a call still waiting for the database gives up."""
        self._closed.set()
        self._engine.dispose()

    def _holder(self, robot: str) -> Controller | None:
        with self._engine.connect() as connection:
            row = connection.execute(
                select(_C.robot, _C.run_id, _C.user_id, _C.since, _C.reason).where(_C.robot == robot)
            ).first()
        if row is None:
            return None
        return Controller(row.robot, row.run_id, row.user_id, utc(row.since), row.reason)

    def _retrying(self, action: Callable[[], _T]) -> _T:
        """``action()``, again after a lost database, for up to the outage budget."""
        first_failure: float | None = None
        delay = _FIRST_RETRY
        while True:
            try:
                return action()
            except (OperationalError, InterfaceError) as exc:
                now = time.monotonic()
                if first_failure is None:
                    first_failure = now
                    log.warning(
                        "robot control in %s unreachable (%s): waiting up to %g s",
                        self.location,
                        str(getattr(exc, "orig", exc)).splitlines()[0],
                        self.outage_budget,
                    )
                if now - first_failure >= self.outage_budget or self._closed.is_set():
                    raise AuditLogUnavailable(self.location, str(getattr(exc, "orig", exc)).splitlines()[0]) from exc
                self._closed.wait(min(delay, self.outage_budget - (now - first_failure)))
                delay = min(delay * 2, _LONGEST_RETRY)
