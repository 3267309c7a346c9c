"""rosbridge v2 vocabulary: op and field names, close codes, and the errors a request can raise.

Every name the wire uses lives here, so handlers never spell a protocol string twice.  Every
failure a handler can meet is a :class:`BridgeError` subclass carrying the reason a client
should read; ``server.Session`` turns them into answers at one boundary (``service_response``,
``action_result`` or ``status``), so nothing is dropped silently.
"""

from __future__ import annotations

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

# --- status levels (set_level / status) ------------------------------------------------------
LEVELS = ("info", "warning", "error", "none")
"""Ordered from most to least verbose; ``none`` (the default) sends no status at all."""

# --- compression -----------------------------------------------------------------------------
COMPRESSION_NONE = "none"
COMPRESSION_PNG = "png"
COMPRESSION_CBOR = "cbor"
COMPRESSION_CBOR_RAW = "cbor-raw"
COMPRESSIONS = (COMPRESSION_NONE, COMPRESSION_PNG, COMPRESSION_CBOR, COMPRESSION_CBOR_RAW)

# --- WebSocket close codes (RFC 6455) --------------------------------------------------------
CLOSE_POLICY_VIOLATION = 1008
CLOSE_MESSAGE_TOO_BIG = 1009

# --- texts clients match on (rosbridge 2.x wording) -----------------------------------------
SERVICE_TIMEOUT_TEXT = "Timeout exceeded while waiting for service response"

#: goal status values of action_msgs/GoalStatus used in action_result
GOAL_STATUS_UNKNOWN = 0
GOAL_STATUS_SUCCEEDED = 4
GOAL_STATUS_CANCELED = 5
GOAL_STATUS_ABORTED = 6


class BridgeError(Exception):
    """A request could not be served; ``str(error)`` is the reason the client reads."""


class MalformedMessage(BridgeError):
    """The frame is not a JSON object with a string ``op``."""


class UnknownOperation(BridgeError):
    """The ``op`` names no operation of rosbridge v2."""


class InvalidField(BridgeError):
    """A field is missing or has the wrong type; the message names field and expected type."""


class UnknownType(BridgeError):
    """A message, service or action type name does not resolve to an installed interface."""


class TopicNotEstablished(BridgeError):
    """A topic was used without a type and nothing on the ROS graph tells its type."""


class TypeConflict(BridgeError):
    """A topic or service is already in use with another type."""


class ServiceUnavailable(BridgeError):
    """No ROS server answers for the called service."""


class ServiceTimeout(BridgeError):
    """The service server did not answer within the call's timeout."""


class ActionFailed(BridgeError):
    """An action goal was rejected, or its server went away."""


class Refused(BridgeError):
    """The server's allow-list (glob) or authentication refuses the request."""


def require(message: dict[str, Any], field: str, kind: type | tuple[type, ...]) -> Any:
    """Return ``message[field]``, raising :class:`InvalidField` naming the expected type."""
    if field not in message:
        raise InvalidField(f"missing field '{field}' ({_kind_name(kind)})")
    return _check(message, field, kind)


def optional(message: dict[str, Any], field: str, kind: type | tuple[type, ...], default: Any = None) -> Any:
    """Return ``message[field]`` if present and not null, else ``default``; type-checked."""
    if message.get(field) is None:
        return default
    return _check(message, field, kind)


def _check(message: dict[str, Any], field: str, kind: type | tuple[type, ...]) -> Any:
    value = message[field]
    kinds = kind if isinstance(kind, tuple) else (kind,)
    # bool is an int in Python, but a JSON true is never a valid count or rate.
    if isinstance(value, bool) and bool not in kinds:
        raise InvalidField(f"field '{field}' must be {_kind_name(kind)}, got {value!r}")
    if float in kinds and isinstance(value, int) and not isinstance(value, bool):
        return float(value)
    if not isinstance(value, kinds):
        raise InvalidField(f"field '{field}' must be {_kind_name(kind)}, got {type(value).__name__} {_short(value)}")
    return value


def _kind_name(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    names = {str: "a string", int: "an integer", float: "a number", bool: "a boolean", dict: "an object", list: "a list"}
    return " or ".join(names.get(k, k.__name__) for k in kinds)


def _short(value: Any, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."
