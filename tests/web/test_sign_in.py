"""Sessions and slowed guessing, on a clock the test turns (units of sign_in.py and sign_in_throttle.py).

The accounts are real (argon2 hashes in a SQLite file); only time is the test's, so limits of
minutes and hours are checked without waiting for them.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from starlette.requests import Request

from console.accounts import AccountStore
from console.sign_in import COOKIE, SessionLimits, SignInRefused, SignIns
from console.sign_in_throttle import Allowance, SignInThrottle
from ground.change_feed import ChangeNotice


class Clock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def request_with(token: str) -> Request:
    return Request(
        {"type": "http", "method": "GET", "path": "/", "headers": [(b"cookie", f"{COOKIE}={token}".encode())]}
    )


@pytest.fixture
def store(tmp_path: Path) -> Iterator[AccountStore]:
    accounts = AccountStore(f"sqlite:///{tmp_path / 'ground.db'}")
    accounts.add("alice", "operator", "alice-secret-1")
    yield accounts
    accounts.close()


def test_the_wait_grows_after_the_free_failures_up_to_its_ceiling_and_is_forgotten_later() -> None:
    clock = Clock()
    throttle = SignInThrottle(
        pair=Allowance(3, 8.0), address=Allowance(100, 60.0), user=Allowance(100, 60.0), window=600.0, clock=clock
    )
    waits = []
    for _ in range(7):
        waits.append(throttle.wait("alice", "10.0.0.9"))
        throttle.failed("alice", "10.0.0.9")
    assert waits == [0, 0, 0, 1, 2, 4, 8]  # free, then doubling from the last failure
    assert throttle.wait("alice", "10.0.0.9") == 8  # capped
    clock.now += 8
    assert throttle.wait("alice", "10.0.0.9") == 0  # waited it out: may try again
    assert throttle.wait("alice", "10.0.0.7") == 0 and throttle.wait("bob", "10.0.0.9") == 0
    clock.now += 600
    throttle.failed("alice", "10.0.0.9")
    assert throttle.wait("alice", "10.0.0.9") == 0  # the old failures left the window


def test_a_guesser_trying_many_users_is_slowed_per_address_and_a_success_clears_the_user() -> None:
    clock = Clock()
    throttle = SignInThrottle(
        pair=Allowance(5, 60.0), address=Allowance(4, 300.0), user=Allowance(20, 60.0), clock=clock
    )
    for user in ("u1", "u2", "u3", "u4"):
        throttle.failed(user, "10.6.6.6")
    assert throttle.wait("u5", "10.6.6.6") == 1  # a user it never tried, from the same address
    assert throttle.wait("u5", "10.0.0.1") == 0
    throttle = SignInThrottle(
        pair=Allowance(5, 60.0), address=Allowance(100, 300.0), user=Allowance(5, 60.0), clock=clock
    )
    for _ in range(4):
        throttle.failed("alice", "10.0.0.1")
    throttle.succeeded("alice", "10.0.0.1")
    throttle.failed("alice", "10.0.0.1")
    assert throttle.wait("alice", "10.0.0.1") == 0  # counted from the success on: one failure, not five


def test_sessions_end_when_idle_at_their_limit_and_when_the_password_changes(store: AccountStore) -> None:
    clock = Clock()
    sign_ins = SignIns(store, limits=SessionLimits(idle=600, absolute=3600, recheck=5), clock=clock)
    with pytest.raises(SignInRefused) as refused:
        sign_ins.sign_in("alice", "wrong-password", "10.0.0.1")
    assert refused.value.status == 401
    session = sign_ins.sign_in("alice", "alice-secret-1", "10.0.0.1")
    assert session.csrf_matches(session.csrf) and not session.csrf_matches("x" * 43) and not session.csrf_matches(None)

    for _ in range(6):  # used every 9 minutes: never idle for 10, but ...
        clock.now += 540
        assert sign_ins.session(request_with(session.token)).account.user == "alice"
    clock.now += 540
    with pytest.raises(SignInRefused, match="time limit"):  # ... 63 minutes after sign-in is past the hour
        sign_ins.session(request_with(session.token))

    idle = sign_ins.sign_in("alice", "alice-secret-1", "10.0.0.1")
    clock.now += 601
    with pytest.raises(SignInRefused, match="inactivity"):
        sign_ins.session(request_with(idle.token))

    changed = sign_ins.sign_in("alice", "alice-secret-1", "10.0.0.1")
    store.set_password("alice", "alice-secret-2")
    clock.now += 6
    with pytest.raises(SignInRefused, match="password changed"):
        sign_ins.session(request_with(changed.token))
    with pytest.raises(SignInRefused, match="password changed: sign in again"):  # it stays ended, with its reason
        sign_ins.session(request_with(changed.token))


def test_an_announced_account_change_is_checked_at_the_next_use_not_after_the_recheck_period(
    store: AccountStore,
) -> None:
    clock = Clock()
    sign_ins = SignIns(store, limits=SessionLimits(recheck=5), clock=clock)
    alice = sign_ins.sign_in("alice", "alice-secret-1", "10.0.0.1")
    store.add("bob", "operator", "bob-secret-12")
    bob = sign_ins.sign_in("bob", "bob-secret-12", "10.0.0.1")
    store.remove("alice")  # another console's change: this one learns of it from the change feed
    assert sign_ins.session(request_with(alice.token)).account.user == "alice"  # not rechecked yet (no time passed)
    sign_ins.notice(ChangeNotice("accounts", "alice"))
    with pytest.raises(SignInRefused, match="account or password changed"):
        sign_ins.session(request_with(alice.token))
    assert sign_ins.session(request_with(bob.token)).account.user == "bob"  # another user's sessions stay


def test_failed_sign_ins_are_refused_with_a_wait_before_the_password_is_even_checked(store: AccountStore) -> None:
    clock = Clock()
    sign_ins = SignIns(store, throttle=SignInThrottle(pair=Allowance(2, 60.0), clock=clock), clock=clock)
    for _ in range(2):
        with pytest.raises(SignInRefused):
            sign_ins.sign_in("alice", "guess", "10.0.0.2")
    with pytest.raises(SignInRefused) as slowed:
        sign_ins.sign_in("alice", "alice-secret-1", "10.0.0.2")
    assert (slowed.value.status, slowed.value.retry_after) == (429, 1)
    clock.now += 1
    assert sign_ins.sign_in("alice", "alice-secret-1", "10.0.0.2").account.user == "alice"


def test_a_second_operator_signs_an_approval_with_their_own_password_and_guessing_it_is_slowed(
    store: AccountStore,
) -> None:
    store.add("bob", "operator", "bob-secret-1")
    store.add("olga", "observer", "olga-secret-1")
    clock = Clock()
    sign_ins = SignIns(store, throttle=SignInThrottle(pair=Allowance(2, 60.0), clock=clock), clock=clock)
    assert sign_ins.second_operator("bob", "bob-secret-1", "10.0.0.2", for_user="alice").user == "bob"
    with pytest.raises(SignInRefused, match="a second operator must approve, not alice"):
        sign_ins.second_operator("alice", "alice-secret-1", "10.0.0.2", for_user="alice")
    with pytest.raises(SignInRefused, match="olga is an observer: only an operator approves commands"):
        sign_ins.second_operator("olga", "olga-secret-1", "10.0.0.2", for_user="alice")
    for _ in range(2):
        with pytest.raises(SignInRefused, match="wrong user id or password"):
            sign_ins.second_operator("bob", "guess", "10.0.0.2", for_user="alice")
    with pytest.raises(SignInRefused) as slowed:  # the same throttle as the sign-in page's
        sign_ins.second_operator("bob", "bob-secret-1", "10.0.0.2", for_user="alice")
    assert slowed.value.status == 429
