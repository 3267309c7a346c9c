"""The world lock gives way: a thread waiting for the world gets it before the stepper takes it
again, however soon the stepper comes back (sim/world_lock.py)."""

from __future__ import annotations

import threading

from sim.world_lock import WorldLock


def _waiting(lock: WorldLock, count: int) -> None:
    """Until ``count`` threads wait for the lock (read under the lock's own condition)."""
    with lock._waiters:
        assert lock._waiters.wait_for(lambda: lock._waiting == count, 30.0)


def test_a_waiting_thread_has_the_world_before_the_stepper_takes_it_again() -> None:
    lock = WorldLock()
    order: list[str] = []
    taken = threading.Event()

    def callback() -> None:  # a ROS callback: a trajectory goal, a halt
        with lock:
            order.append("callback")
            taken.set()

    with lock:  # the stepper in a step
        waiter = threading.Thread(target=callback)
        waiter.start()
        _waiting(lock, 1)
    lock.give_way()
    assert taken.is_set(), "give_way returned before the waiting thread had the lock"
    with lock:
        order.append("stepper")
    waiter.join()
    assert order == ["callback", "stepper"]


def test_nobody_waiting_costs_the_stepper_nothing_and_the_lock_is_reentrant() -> None:
    lock = WorldLock()
    lock.give_way()
    with lock, lock:  # Simulation.halt under a callback that already holds the world
        pass
    lock.give_way()
