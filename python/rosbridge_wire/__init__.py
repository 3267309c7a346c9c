"""The rosbridge v2 wire: op names, codes, and the login signature, for the bridge and its clients.

One vocabulary for both ends in Python: the habitat's bridge (:mod:`bridge.rosbridge`) and the
ground's clients (the console's 3D view link). A leaf: it imports no Caretaker package, so both
sides may use it (tests/foundation/test_package_graph.py). The Java client
(``caretaker.rosbridge.RosAuth``) signs the same way.

Login (``op: auth``) with a shared secret is either a bearer token, or a MAC over rosauth's fields:
HMAC-SHA256(SECRET, client + dest + rand + str(t) + level + str(end)), ``t`` the client's Unix
time and ``end`` the end of validity (:func:`signed_login`, checked by :func:`login_mac`).
"""

from __future__ import annotations

import hashlib
import hmac
import secrets
from collections.abc import Mapping
from typing import Any

# --- ops -----------------------------------------------------------------------------------
OP_ADVERTISE = "advertise"
OP_UNADVERTISE = "unadvertise"
OP_PUBLISH = "publish"
OP_SUBSCRIBE = "subscribe"
OP_UNSUBSCRIBE = "unsubscribe"
OP_CALL_SERVICE = "call_service"
OP_SERVICE_RESPONSE = "service_response"
OP_ADVERTISE_SERVICE = "advertise_service"
OP_UNADVERTISE_SERVICE = "unadvertise_service"
OP_SEND_ACTION_GOAL = "send_action_goal"
OP_CANCEL_ACTION_GOAL = "cancel_action_goal"
OP_ACTION_FEEDBACK = "action_feedback"
OP_ACTION_RESULT = "action_result"
OP_ADVERTISE_ACTION = "advertise_action"
OP_UNADVERTISE_ACTION = "unadvertise_action"
OP_FRAGMENT = "fragment"
OP_PNG = "png"
OP_SET_LEVEL = "set_level"
OP_STATUS = "status"
OP_AUTH = "auth"

# --- WebSocket close codes (RFC 6455) --------------------------------------------------------
CLOSE_POLICY_VIOLATION = 1008
CLOSE_MESSAGE_TOO_BIG = 1009
CLOSE_TRY_AGAIN_LATER = 1013

#: goal status values of action_msgs/GoalStatus used in action_result
GOAL_STATUS_UNKNOWN = 0
GOAL_STATUS_SUCCEEDED = 4
GOAL_STATUS_CANCELED = 5
GOAL_STATUS_ABORTED = 6

# --- login -----------------------------------------------------------------------------------
MAC_FIELDS = ("client", "dest", "rand", "t", "level", "end")
"""The fields of a MAC login, in the order the MAC covers them (rosauth's)."""
LOGIN_LIFETIME_S = 60.0
"""How long a login a client signs stays valid once it has arrived (its trip across the link comes
on top: :attr:`rosbridge_wire.light_time.LightTime.login_lifetime`)."""


def login_mac(secret: str | bytes, fields: Mapping[str, Any]) -> str:
    """The hex HMAC-SHA256 of a login's :data:`MAC_FIELDS` under ``secret``."""
    key = secret.encode() if isinstance(secret, str) else secret
    text = "".join(str(fields[name]) for name in MAC_FIELDS)
    return hmac.new(key, text.encode("utf-8", "replace"), hashlib.sha256).hexdigest()


def signed_login(
    secret: str, client: str, dest: str, now: float, *, level: str = "user", lifetime: float = LOGIN_LIFETIME_S
) -> dict[str, Any]:
    """An ``auth`` message for ``dest`` (the bridge's URL) signed with ``secret``, valid from
    ``now`` (Unix seconds) for ``lifetime`` s (across a long link: its light time's
    ``login_lifetime``, or it expires on the way)."""
    fields: dict[str, Any] = {
        "client": client,
        "dest": dest,
        "rand": secrets.token_hex(16),
        "t": now,
        "level": level,
        "end": now + lifetime,
    }
    return {"op": OP_AUTH, "mac": login_mac(secret, fields), **fields}
