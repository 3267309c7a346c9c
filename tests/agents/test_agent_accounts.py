"""Accounts of role ``agent``: no password, tokens printed once and stored as hashes, expiring and revocable.

Real ground databases (a SQLite file, and the session's PostgreSQL where the command runs as the
owner and the agent as the runner role), ``caretaker accounts`` as an operator types it.
"""

from __future__ import annotations

import io
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from sqlalchemy import select, update

from console.accounts import AccountStore
from console.accounts_command import main as accounts
from console.sign_in import SignInRefused, SignIns
from records.agent_tables import agent_tokens
from records.agent_tokens import TOKEN_PREFIX, TokenRefused, TokenStore, token_hash
from support.web_server import GroundDatabase, new_ground_database

pytestmark = pytest.mark.slow(seconds=45)


@pytest.fixture(params=["sqlite", "postgresql"])
def database(request: pytest.FixtureRequest, tmp_path: Path) -> GroundDatabase:
    postgres = request.getfixturevalue("postgres") if request.param == "postgresql" else None
    return new_ground_database(request.param, tmp_path, postgres)


def command(db: str, *argv: str, stdin: str = "") -> tuple[int, str, str]:
    """``caretaker accounts --db DB ARGV``: exit code, stdout, stderr."""
    out, err = io.StringIO(), io.StringIO()
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr("sys.stdin", io.StringIO(stdin))
        patch.setattr("sys.stdout", out)
        patch.setattr("sys.stderr", err)
        code = accounts(["--db", db, *argv])
    return code, out.getvalue(), err.getvalue()


def agent_store(url: str) -> tuple[AccountStore, TokenStore]:
    store = AccountStore(url)
    return store, TokenStore(store.engine)


def test_a_token_is_printed_once_and_only_its_hash_is_kept(database: GroundDatabase) -> None:
    code, out, err = command(database.owner_url, "add", "daphne", "--role", "agent")
    assert (code, out) == (0, "added daphne (agent)\n"), err
    code, out, err = command(database.owner_url, "token", "daphne", "--expires-in", "7d")
    assert code == 0, err
    token = out.strip()
    assert token.startswith(TOKEN_PREFIX) and len(token) > 40 and "\n" not in token
    assert "shown once" in err and "valid until" in err
    store, tokens = agent_store(database.owner_url)
    try:
        with store.engine.connect() as connection:
            stored = connection.execute(select(agent_tokens)).one()
        assert stored.token_sha256 == token_hash(token) and token not in str(stored._mapping)
        assert stored.expires is not None
        # the agent, connecting as the consoles' (runner) role, is who it says
        runner_store, runner_tokens = agent_store(database.url)
        try:
            assert runner_tokens.authenticate(token) == "daphne"
            assert runner_tokens.authenticate(token, agent="daphne") == "daphne"
        finally:
            runner_store.close()
        _, listed, _ = command(database.owner_url, "tokens", "daphne")
        assert listed.startswith("1\tissued ") and "valid until" in listed and token not in listed
    finally:
        store.close()


def test_expired_revoked_unknown_and_other_accounts_tokens_are_refused(database: GroundDatabase) -> None:
    for name in ("daphne", "hal"):
        assert command(database.owner_url, "add", name, "--role", "agent")[0] == 0
    daphne = command(database.owner_url, "token", "daphne")[1].strip()
    hal = command(database.owner_url, "token", "hal", "--expires-in", "1h")[1].strip()
    store, tokens = agent_store(database.owner_url)
    try:
        assert tokens.authenticate(hal) == "hal"

        def refusal(token: str, agent: str | None = None) -> str:
            with pytest.raises(TokenRefused) as refused:
                tokens.authenticate(token, agent=agent)
            return f"{refused.value.rule}: {refused.value.message}"

        assert refusal(hal, agent="daphne") == "agent_token: this token belongs to another account, not to daphne"
        assert refusal(daphne[:-1] + ("A" if daphne[-1] != "A" else "B")).startswith("agent_token: unknown token")
        assert refusal("").startswith("agent_token: no token")
        with store.engine.begin() as connection:  # an hour on: hal's token ran out
            connection.execute(
                update(agent_tokens)
                .where(agent_tokens.c.user_id == "hal")
                .values(expires=datetime.now(UTC) - timedelta(seconds=1))
            )
        assert refusal(hal).startswith("agent_token: the token of hal expired at ")
        assert command(database.owner_url, "revoke", "daphne")[1] == "revoked 1 tokens of daphne\n"
        assert refusal(daphne).startswith("agent_token: the token of daphne was revoked at ")
        fresh = command(database.owner_url, "token", "daphne")[1].strip()
        assert tokens.authenticate(fresh) == "daphne"  # revoking ended the old ones, not the account
        code, _, err = command(database.owner_url, "revoke", "daphne", "7")
        assert code == 2 and "daphne has no token 7" in err
        assert command(database.owner_url, "set-role", "daphne", "observer")[0] == 0
        assert refusal(fresh) == "agent_role: daphne is an observer now, not an agent"
        assert command(database.owner_url, "remove", "daphne")[0] == 0
        assert refusal(fresh) == "agent_token: the account daphne no longer exists"
    finally:
        store.close()


def test_an_agent_has_no_password_and_never_signs_in_to_the_console(tmp_path: Path) -> None:
    db = f"sqlite:///{tmp_path / 'ground.db'}"
    assert command(db, "add", "daphne", "--role", "agent")[0] == 0
    code, _, err = command(db, "set-password", "daphne", stdin="a long password\n")
    assert code == 2 and "daphne is an agent: it has no password" in err
    code, _, err = command(db, "token", "nobody")
    assert code == 2 and "no account 'nobody'" in err
    assert command(db, "add", "alice", "--role", "operator", stdin="alice's password\n")[0] == 0
    code, _, err = command(db, "token", "alice")
    assert code == 2 and "alice is an operator: only an agent has tokens" in err
    store = AccountStore(db)
    sign_ins = SignIns(store)
    try:
        assert sign_ins.sign_in("alice", "alice's password", "127.0.0.1").account.user == "alice"
        # an operator made an agent loses the password, so the account can no longer sign in
        store.set_role("alice", "agent")
        for user, password in (("alice", "alice's password"), ("daphne", ""), ("daphne", "!agent")):
            with pytest.raises(SignInRefused) as refused:
                sign_ins.sign_in(user, password, "127.0.0.2")
            assert refused.value.status == 401
        assert store.verify("alice", "alice's password") is None
    finally:
        store.close()
