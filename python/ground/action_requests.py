"""Operator actions on a run hosted elsewhere: forwarded to its host through the database, answered back.

A console whose operator acts on a run that another process hosts (:mod:`ground.run_hosts`)
inserts a row into ``run_action_requests`` (state ``pending``, the host's id, the user and the
action as JSON); the insert NOTIFYs the host (:mod:`ground.change_feed`). The host *takes*
the request (``pending`` → ``taken``, one atomic UPDATE), performs it as that user — checking
the user's role itself, against the accounts table — and writes the answer (``done`` with the
result, or ``refused`` with the HTTP status and message the host's own page would have had),
which NOTIFYs the requester.

Exactly once, whatever the timing: the requester waits :data:`TAKE_WITHIN_S` for the host to
take the request, then withdraws it (``pending`` → ``expired``, atomic too). Either the host took
it first, and then it will answer, or the withdrawal won, and the action was never performed and
never will be. A taken request unanswered after :data:`ANSWER_WITHIN_S` has an unknown outcome,
and the requester says so (the run's log shows what happened).

On its way: a host whose answer comes from far away (an onboard run's supervisor, across the
link's light time) says when it sent the action on and when its answer is due
(:meth:`ForwardedAction.on_its_way`: ``taken`` → ``sent``, with the answer's due time and the
time after which none can come). The requester then waits for the answer until it is due, and no
longer than it would for any host: an answer due later is reported "on its way, expected at T"
(status 202, with the request's id), and :meth:`ActionRequests.progress` tells what became of it
afterwards: still on its way, ``unknown`` once it is due and none came (the answer may still come
until the host gives up), then the answer or a final ``unknown``.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import Any

from sqlalchemy import insert, select, update
from sqlalchemy.engine import Engine
from sqlalchemy.exc import SQLAlchemyError

from ground.change_feed import ChangeNotice
from records.console_tables import run_action_requests

__all__ = ["ANSWER_WITHIN_S", "TAKE_WITHIN_S", "ActionRequests", "Answer", "ForwardedAction", "OnItsWay"]

log = logging.getLogger(__name__)

#: How long a host has to take a request before the requester withdraws it (never performed).
TAKE_WITHIN_S = 5.0
#: How long a taken request may go unanswered before its outcome is reported unknown, and how long
#: a requester waits for any answer (one due later is reported on its way).
ANSWER_WITHIN_S = 30.0

#: A host says an action went on to where it is done: (its answer due at, none after), epoch s.
OnItsWay = Callable[[float, float], None]

_R = run_action_requests.c


@dataclass(frozen=True)
class ForwardedAction:
    """A request as its host reads it: who asks (user, from which console), on which run, what."""

    request_id: int
    run_id: str
    user: str
    console: str
    action: dict[str, Any]
    told: OnItsWay | None = field(default=None, compare=False, repr=False)

    def on_its_way(self, expected_at: float, gives_up_at: float) -> None:
        """The host sent the action on: its answer is due at ``expected_at``, none comes after
        ``gives_up_at`` (epoch s); the requester says so until the answer comes."""
        if self.told is not None:
            self.told(expected_at, gives_up_at)


@dataclass(frozen=True)
class Answer:
    """What became of an action: an HTTP-like ``status`` and the body (``{"error": ...}`` unless 2xx)."""

    status: int
    body: dict[str, Any]

    @property
    def ok(self) -> bool:
        return 200 <= self.status < 300


Performer = Callable[[ForwardedAction], Answer]


class ActionRequests:
    """Both ends of forwarding for one process: :meth:`forward` asks, ``perform`` answers requests to ``host_id``.

    Subscribe :meth:`notice` to the process's change feed.
    """

    def __init__(self, engine: Engine, *, host_id: str, console: str, perform: Performer, aside: bool = False) -> None:
        """``aside``: perform each taken request on a thread of its own, for a host whose performing
        waits on a far habitat (an action waiting for its answer must not keep a Halt from being
        taken within :data:`TAKE_WITHIN_S`); otherwise one at a time, in order."""
        self._engine = engine
        self._host_id = host_id
        self._console = console[:200]
        self._perform = perform
        self._aside = aside
        self._lock = threading.Lock()  # guards _waiting
        self._waiting: dict[int, threading.Event] = {}
        self._inbox: queue.Queue[int | None] = queue.Queue()
        self._worker = threading.Thread(target=self._serve, name="forwarded-actions", daemon=True)
        self._worker.start()

    # ---- asking -------------------------------------------------------------------------------
    def forward(
        self,
        run_id: str,
        host_id: str,
        user: str,
        action: dict[str, Any],
        *,
        take_within: float = TAKE_WITHIN_S,
        answer_within: float = ANSWER_WITHIN_S,
    ) -> Answer:
        """Have the host of ``run_id`` perform ``action`` as ``user``; its answer, or 504 saying what is known."""
        arrived = threading.Event()
        with self._engine.begin() as connection:
            request_id = int(
                connection.execute(
                    insert(run_action_requests)
                    .values(
                        run_id=run_id,
                        host_id=host_id,
                        user_id=user,
                        console=self._console,
                        action=json.dumps(action),
                        state="pending",
                        requested=datetime.now(UTC),
                    )
                    .returning(_R.id)
                ).scalar_one()
            )
        with self._lock:
            self._waiting[request_id] = arrived
        try:
            started = time.monotonic()
            state = self._state(request_id)
            while state == "pending":
                if not arrived.wait(max(0.0, take_within - (time.monotonic() - started))) and self._withdraw(
                    request_id
                ):
                    return Answer(
                        504,
                        {
                            "error": f"the run's host did not take the {action.get('action')!r} request "
                            f"within {take_within:g} s: it was not performed"
                        },
                    )
                arrived.clear()
                state = self._state(request_id)
            patience = time.time() + take_within + answer_within - (time.monotonic() - started)
            while state in ("taken", "sent"):
                # an answer due (sent) before the requester's patience runs out is waited for until
                # due; one due later is on its way, and said so at once
                due = self._due(request_id)[0] if state == "sent" else patience
                if due > patience:
                    return Answer(202, {"result": self.progress(request_id)})
                if not arrived.wait(max(0.0, min(due, patience) - time.time())):
                    state = self._state(request_id)
                    if state == "sent":
                        return Answer(202, {"result": self.progress(request_id)})
                    if state == "taken":
                        return Answer(
                            504,
                            {
                                "error": f"the run's host took the {action.get('action')!r} request but has not "
                                f"answered in {answer_within:g} s: its outcome is unknown (see the run's log)"
                            },
                        )
                    break
                arrived.clear()
                state = self._state(request_id)
            return self._answer(request_id)
        finally:
            with self._lock:
                self._waiting.pop(request_id, None)

    def _state(self, request_id: int) -> str:
        with self._engine.connect() as connection:
            return str(connection.scalar(select(_R.state).where(_R.id == request_id)))

    def _withdraw(self, request_id: int) -> bool:
        """Withdraw a request nobody took; False when the host took it first (it will answer)."""
        with self._engine.begin() as connection:
            return bool(
                connection.execute(
                    update(run_action_requests)
                    .where(_R.id == request_id, _R.state == "pending")
                    .values(state="expired")
                ).rowcount
            )

    def _due(self, request_id: int) -> tuple[float, float]:
        """A sent request's (answer due at, none after), epoch s, as its host said."""
        with self._engine.connect() as connection:
            text = connection.scalar(select(_R.answer).where(_R.id == request_id))
        note = _action(str(text or ""))
        return float(note.get("expected_at", 0.0)), float(note.get("gives_up_at", 0.0))

    def progress(self, request_id: int, run_id: str | None = None) -> dict[str, Any] | None:
        """What became of a request (of ``run_id``, when given) so far; None if there is none.

        ``state``: ``pending`` or ``taken`` (not sent on yet), ``on_its_way`` (its answer is due at
        ``expected_at``), ``unknown`` (due, none came; ``final`` once none can come any more),
        ``done`` (with ``result``), ``refused`` (with ``status`` and ``error``), ``expired`` (never
        performed). Times are epoch s of this ground's clock."""
        with self._engine.connect() as connection:
            row = connection.execute(
                select(_R.run_id, _R.state, _R.status, _R.answer, _R.action).where(_R.id == request_id)
            ).one_or_none()
        if row is None or (run_id is not None and row.run_id != run_id):
            return None
        known: dict[str, Any] = {"request": request_id, "action": _action(row.action).get("action")}
        body = _action(str(row.answer or ""))
        if row.state == "sent":
            expected_at, gives_up_at = float(body.get("expected_at", 0.0)), float(body.get("gives_up_at", 0.0))
            now = time.time()
            state = "on_its_way" if now < expected_at else "unknown"
            return known | {
                "state": state,
                "final": now >= gives_up_at,
                "expected_at": expected_at,
                "gives_up_at": gives_up_at,
            }
        if row.state == "done":
            return known | {"state": "done", "final": True, "result": body.get("result")}
        if row.state == "refused":
            return known | {"state": "refused", "final": True, "status": row.status, "error": body.get("error")}
        if row.state == "expired":
            return known | {"state": "expired", "final": True, "error": "its host did not take it: not performed"}
        return known | {"state": str(row.state), "final": False}

    def _answer(self, request_id: int) -> Answer:
        with self._engine.connect() as connection:
            row = connection.execute(select(_R.status, _R.answer).where(_R.id == request_id)).one()
        return Answer(int(row.status), json.loads(row.answer))

    # ---- answering ----------------------------------------------------------------------------
    def notice(self, notice: ChangeNotice) -> None:
        """Change-feed subscriber: wake a waiting :meth:`forward`, or queue a request made to this host."""
        if notice.channel == "resync":
            self._inbox.put(None)  # look for requests missed while the feed was away
            with self._lock:
                for arrived in self._waiting.values():
                    arrived.set()
            return
        if notice.channel != "actions":
            return
        state, request_id, host_id = (notice.payload.split(" ", 2) + ["", "", ""])[:3]
        if not request_id.isdigit():
            return
        with self._lock:
            waiting = self._waiting.get(int(request_id))
        if waiting is not None:
            waiting.set()
        if state == "pending" and host_id == self._host_id:
            self._inbox.put(int(request_id))

    def close(self) -> None:
        self._inbox.put(-1)
        self._worker.join(10)

    def _serve(self) -> None:
        while True:
            request_id = self._inbox.get()
            if request_id == -1:
                return
            try:
                for pending in self._pending() if request_id is None else [request_id]:
                    self._take_and_answer(pending)
            except SQLAlchemyError as exc:  # the requester withdraws what is not taken; nothing is done twice
                log.warning("cannot serve forwarded actions now: %s", str(exc).splitlines()[0])

    def _pending(self) -> list[int]:
        with self._engine.connect() as connection:
            return list(
                connection.scalars(
                    select(_R.id).where(_R.host_id == self._host_id, _R.state == "pending").order_by(_R.id)
                )
            )

    def _take_and_answer(self, request_id: int) -> None:
        with self._engine.begin() as connection:
            taken = connection.execute(
                update(run_action_requests).where(_R.id == request_id, _R.state == "pending").values(state="taken")
            ).rowcount
            row = connection.execute(
                select(_R.run_id, _R.user_id, _R.console, _R.action).where(_R.id == request_id)
            ).one()
        if not taken:
            return  # withdrawn, or taken already
        request = ForwardedAction(
            request_id,
            row.run_id,
            row.user_id,
            row.console,
            _action(row.action),
            told=lambda expected_at, gives_up_at: self._on_its_way(request_id, expected_at, gives_up_at),
        )
        if self._aside:
            threading.Thread(
                target=self._perform_and_answer, args=(request,), name=f"forwarded-{request_id}", daemon=True
            ).start()
        else:
            self._perform_and_answer(request)

    def _perform_and_answer(self, request: ForwardedAction) -> None:
        """Perform a taken request and write its answer (an answer that cannot be written: its requester
        says the outcome is unknown, as for any host that did not answer)."""
        try:
            answer = self._perform(request)
        except Exception as exc:  # answered all the same: the requester must not wait for nothing
            log.exception("forwarded action %s failed", request)
            answer = Answer(500, {"error": f"the host failed performing it: {type(exc).__name__}: {exc}"})
        log.info(
            "forwarded %s on %s by %s from %s: %s",
            request.action.get("action"),
            request.run_id,
            request.user,
            request.console,
            answer.status,
        )
        try:
            self._write_answer(request.request_id, answer)
        except SQLAlchemyError as exc:
            log.warning("cannot answer forwarded action %s: %s", request.request_id, str(exc).splitlines()[0])

    def _on_its_way(self, request_id: int, expected_at: float, gives_up_at: float) -> None:
        """Note a taken request sent on, and when its answer is due (``taken`` → ``sent``): its
        requester says so. A note that cannot be written leaves the requester waiting as for any
        host; the answer is written all the same."""
        try:
            with self._engine.begin() as connection:
                connection.execute(
                    update(run_action_requests)
                    .where(_R.id == request_id, _R.state == "taken")
                    .values(
                        state="sent",
                        answer=json.dumps({"expected_at": expected_at, "gives_up_at": gives_up_at}),
                    )
                )
        except SQLAlchemyError as exc:
            log.warning("cannot note forwarded action %s on its way: %s", request_id, str(exc).splitlines()[0])

    def _write_answer(self, request_id: int, answer: Answer) -> None:
        with self._engine.begin() as connection:
            connection.execute(
                update(run_action_requests)
                .where(_R.id == request_id)
                .values(
                    state="done" if answer.ok else "refused",
                    status=answer.status,
                    answer=json.dumps(answer.body, default=str),
                    answered=datetime.now(UTC),
                )
            )


def _action(text: str) -> dict[str, Any]:
    try:
        value = json.loads(text)
    except json.JSONDecodeError:
        return {}
    return value if isinstance(value, dict) else {}
