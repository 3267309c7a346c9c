"""An rclpy action client whose answers cannot overtake the records of their requests.

rclpy 7.1 (the Jazzy wheels) sends a goal, result or cancel request and only then records its
sequence number.  Under a MultiThreadedExecutor another thread can take the server's answer in
between: it finds no record, logs "Ignoring unexpected goal response" and drops the answer, and
the caller's future never completes.  The AT server met this as "the trajectory action did not
answer within 10 s" about once in a few hundred goals on a busy machine.  Here sending and
recording a request, and settling an answer, hold one lock, so an answer is handled only
after its request is on record.  It overrides rclpy's private ``_cancel_goal_async`` and
``_get_result_async`` (what ``ClientGoalHandle`` calls), as pinned in requirements.txt.
"""

from __future__ import annotations

import threading
from typing import Any

from rclpy.action import ActionClient

_ANSWERS = ("goal", "cancel", "result")
"""Keys of the data an action client takes that answer one of its requests."""


class RecordedActionClient(ActionClient):
    """``rclpy.action.ActionClient`` with request bookkeeping and answer handling serialized.

    (Its calls of rclpy's methods are marked ``no-untyped-call``: rclpy is not annotated.)
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[no-untyped-call]
        # re-entrant: a future's done-callback, run while an answer is settled, may send a request
        self._records_lock = threading.RLock()

    def send_goal_async(self, goal: Any, feedback_callback: Any = None, goal_uuid: Any = None) -> Any:
        with self._records_lock:
            return super().send_goal_async(goal, feedback_callback, goal_uuid)  # type: ignore[no-untyped-call]

    def _cancel_goal_async(self, goal_handle: Any) -> Any:
        with self._records_lock:
            return super()._cancel_goal_async(goal_handle)  # type: ignore[no-untyped-call]

    def _get_result_async(self, goal_handle: Any) -> Any:
        with self._records_lock:
            return super()._get_result_async(goal_handle)  # type: ignore[no-untyped-call]

    async def execute(self, taken_data: dict[str, Any]) -> None:
        answers = {key: value for key, value in taken_data.items() if key in _ANSWERS}
        if answers:
            # Settling answers awaits nothing, so the lock is held only while this runs through;
            # feedback (a user callback that may suspend) and status updates go on without it.
            with self._records_lock:
                await super().execute(answers)  # type: ignore[no-untyped-call]
        rest = {key: value for key, value in taken_data.items() if key not in _ANSWERS}
        if rest:
            await super().execute(rest)  # type: ignore[no-untyped-call]
