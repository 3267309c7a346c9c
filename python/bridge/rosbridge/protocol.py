"""rosbridge v2 vocabulary: op and field names, close codes, and the errors a request can raise.

Every name the wire uses lives here, so handlers never spell a protocol string twice.  Every
failure a handler can meet is a :class:`BridgeError` subclass carrying the reason a client
should read; ``operations.Bridge`` turns them into answers at one boundary (``service_response``,
``action_result`` or ``status``), so nothing is dropped silently.

Whatever a client sent is hostile until checked, and an answer must never fail to encode:
:func:`echo` and :func:`client_text` make the values and texts an answer carries from client
data (ids, names, reasons) always encodable, bounded and free of server paths.
"""

from __future__ import annotations

import math
import re
import reprlib
from typing import Any

# The wire's own vocabulary (ops, close codes, goal statuses), shared with the clients; re-exported
# so that handlers spell every wire name through this module.
from rosbridge_wire import (
    CLOSE_MESSAGE_TOO_BIG as CLOSE_MESSAGE_TOO_BIG,
)
from rosbridge_wire import (
    CLOSE_POLICY_VIOLATION as CLOSE_POLICY_VIOLATION,
)
from rosbridge_wire import (
    CLOSE_TRY_AGAIN_LATER as CLOSE_TRY_AGAIN_LATER,
)
from rosbridge_wire import (
    GOAL_STATUS_ABORTED as GOAL_STATUS_ABORTED,
)
from rosbridge_wire import (
    GOAL_STATUS_CANCELED as GOAL_STATUS_CANCELED,
)
from rosbridge_wire import (
    GOAL_STATUS_SUCCEEDED as GOAL_STATUS_SUCCEEDED,
)
from rosbridge_wire import (
    GOAL_STATUS_UNKNOWN as GOAL_STATUS_UNKNOWN,
)
from rosbridge_wire import (
    OP_ACTION_FEEDBACK as OP_ACTION_FEEDBACK,
)
from rosbridge_wire import (
    OP_ACTION_RESULT as OP_ACTION_RESULT,
)
from rosbridge_wire import (
    OP_ADVERTISE as OP_ADVERTISE,
)
from rosbridge_wire import (
    OP_ADVERTISE_ACTION as OP_ADVERTISE_ACTION,
)
from rosbridge_wire import (
    OP_ADVERTISE_SERVICE as OP_ADVERTISE_SERVICE,
)
from rosbridge_wire import (
    OP_AUTH as OP_AUTH,
)
from rosbridge_wire import (
    OP_CALL_SERVICE as OP_CALL_SERVICE,
)
from rosbridge_wire import (
    OP_CANCEL_ACTION_GOAL as OP_CANCEL_ACTION_GOAL,
)
from rosbridge_wire import (
    OP_FRAGMENT as OP_FRAGMENT,
)
from rosbridge_wire import (
    OP_PNG as OP_PNG,
)
from rosbridge_wire import (
    OP_PUBLISH as OP_PUBLISH,
)
from rosbridge_wire import (
    OP_SEND_ACTION_GOAL as OP_SEND_ACTION_GOAL,
)
from rosbridge_wire import (
    OP_SERVICE_RESPONSE as OP_SERVICE_RESPONSE,
)
from rosbridge_wire import (
    OP_SET_LEVEL as OP_SET_LEVEL,
)
from rosbridge_wire import (
    OP_STATUS as OP_STATUS,
)
from rosbridge_wire import (
    OP_SUBSCRIBE as OP_SUBSCRIBE,
)
from rosbridge_wire import (
    OP_UNADVERTISE as OP_UNADVERTISE,
)
from rosbridge_wire import (
    OP_UNADVERTISE_ACTION as OP_UNADVERTISE_ACTION,
)
from rosbridge_wire import (
    OP_UNADVERTISE_SERVICE as OP_UNADVERTISE_SERVICE,
)
from rosbridge_wire import (
    OP_UNSUBSCRIBE as OP_UNSUBSCRIBE,
)

# --- status levels (set_level / status) ------------------------------------------------------
LEVELS = ("info", "warning", "error", "none")
"""Ordered from most to least verbose; ``none`` (the default) sends no status at all."""

# --- compression -----------------------------------------------------------------------------
COMPRESSION_NONE = "none"
COMPRESSION_PNG = "png"
COMPRESSION_CBOR = "cbor"
COMPRESSION_CBOR_RAW = "cbor-raw"
COMPRESSIONS = (COMPRESSION_NONE, COMPRESSION_PNG, COMPRESSION_CBOR, COMPRESSION_CBOR_RAW)

# --- services the bridge answers itself -------------------------------------------------------
CONNECTION_STATS = "/rosbridge/connection_stats"
"""Answers with the calling connection's traffic (bytes and messages each way, seconds open)."""

# --- texts clients match on (rosbridge 2.x wording) -----------------------------------------
SERVICE_TIMEOUT_TEXT = "Timeout exceeded while waiting for service response"


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


class ServiceUnanswered(BridgeError):
    """A request to a client-served service ends without an answer: the ROS caller gets none
    (a ROS service cannot report failure) and its own timeout tells it."""


class ActionFailed(BridgeError):
    """An action goal was rejected, or its server went away."""


class Refused(BridgeError):
    """The server's allow-list (glob) or authentication refuses the request."""


class InvalidName(BridgeError):
    """A topic, service or action name is not a valid ROS name."""


class OverQuota(BridgeError):
    """The request would exceed one of the bridge's quotas (docs/rosbridge.md, Limits)."""


# --- values that leave the bridge ------------------------------------------------------------
MAX_ECHO_INT = 2**63
"""Ids are echoed if they fit 64 bits: every JSON library of the clients reads those."""
MAX_TEXT = 300
"""Characters of client data quoted in an answer or a log line."""
_SOURCE_PATH = re.compile(r"(?:\bat )?(?:[\w.~-]*/)+[\w.-]+\.(?:py|pyx|c|cc|cpp|h|hpp|so)\b(?::\d+)?")
_REPR = reprlib.Repr()
_REPR.maxlevel, _REPR.maxstring, _REPR.maxother, _REPR.maxlist, _REPR.maxdict = 2, 40, 40, 4, 4


def echo(value: Any) -> str | int | None:
    """``value`` as an id or name to copy into an answer, or None when it cannot be one.

    Strings are made encodable (a lone surrogate becomes its ``\\udXXX`` escape) and ints must
    fit 64 bits; anything else (NaN, objects, 4,000-digit numbers) is not echoed.
    """
    if isinstance(value, str):
        return encodable(value)
    if isinstance(value, int) and not isinstance(value, bool) and -MAX_ECHO_INT <= value < MAX_ECHO_INT:
        return value
    return None


def encodable(text: str) -> str:
    """``text`` with anything UTF-8 cannot carry (lone surrogates) replaced by its escape."""
    if text.isascii():
        return text
    try:
        text.encode("utf-8")
        return text
    except UnicodeEncodeError:
        return text.encode("utf-8", "backslashreplace").decode("utf-8")


def client_text(text: str, limit: int = MAX_TEXT) -> str:
    """A reason or log text safe to send or log: encodable, at most ``limit`` characters, and
    without source paths (rcl's errors name C files and lines, Python's module files)."""
    if len(text) > limit:  # first: the path pattern is quadratic in the length it scans
        text = text[: limit - 3] + "..."
    return _SOURCE_PATH.sub("<source>", encodable(text))


def describe(value: Any) -> str:
    """A short description of a client value for an error text (bounded however large or deep)."""
    if isinstance(value, int) and not isinstance(value, bool) and abs(value) >= 10**40:
        return f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits"
    return f"{type(value).__name__} {client_text(_REPR.repr(value), 60)}"


Bounds = tuple[float, float]


def require(message: dict[str, Any], field: str, kind: type | tuple[type, ...], bounds: Bounds | None = None) -> Any:
    """Return ``message[field]``, raising :class:`InvalidField` naming the expected type (and,
    for numbers, the range ``bounds``, inclusive)."""
    if field not in message:
        raise InvalidField(f"missing field '{field}' ({_kind_name(kind)})")
    return _check(message, field, kind, bounds)


def optional(
    message: dict[str, Any],
    field: str,
    kind: type | tuple[type, ...],
    default: Any = None,
    bounds: Bounds | None = None,
) -> Any:
    """Return ``message[field]`` if present and not null, else ``default``; checked as :func:`require`."""
    if message.get(field) is None:
        return default
    return _check(message, field, kind, bounds)


def _check(message: dict[str, Any], field: str, kind: type | tuple[type, ...], bounds: Bounds | None) -> Any:
    value = message[field]
    kinds = kind if isinstance(kind, tuple) else (kind,)
    # bool is an int in Python, but a JSON true is never a valid count or rate.
    if isinstance(value, bool) and bool not in kinds:
        raise InvalidField(f"field '{field}' must be {_kind_name(kind)}, got {value!r}")
    if float in kinds and isinstance(value, int) and not isinstance(value, bool):
        if abs(value) > 2**53:  # not a number the bridge needs, and float() of 400 digits overflows
            raise InvalidField(f"field '{field}' must be {_kind_name(kind)} of a sensible size, got {describe(value)}")
        value = float(value)
    if not isinstance(value, kinds):
        raise InvalidField(f"field '{field}' must be {_kind_name(kind)}, got {describe(value)}")
    if isinstance(value, float) and not math.isfinite(value):
        raise InvalidField(f"field '{field}' must be a finite number, got {value!r}")
    if bounds is None and isinstance(value, int) and not isinstance(value, bool):
        bounds = (-MAX_ECHO_INT, MAX_ECHO_INT - 1)
    if bounds is not None and isinstance(value, (int, float)) and not isinstance(value, bool):
        low, high = bounds
        if not low <= value <= high:
            raise InvalidField(
                f"field '{field}' must be between {_number(low)} and {_number(high)}, got {describe(value)}"
            )
    return value


def _number(value: float) -> str:
    return str(int(value)) if float(value).is_integer() else str(value)


def _kind_name(kind: type | tuple[type, ...]) -> str:
    kinds = kind if isinstance(kind, tuple) else (kind,)
    names = {
        str: "a string",
        int: "an integer",
        float: "a number",
        bool: "a boolean",
        dict: "an object",
        list: "a list",
    }
    return " or ".join(names.get(k, k.__name__) for k in kinds)
