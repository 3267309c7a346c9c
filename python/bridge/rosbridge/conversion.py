"""ROS messages <-> JSON-ready dicts for any installed interface, by rosidl introspection.

The public functions other parts use (the command ledger turns JSON requests into ROS messages
with the same checks):

* :func:`load_type` ``("pkg/srv/T", "srv")`` -> the interface class; raises :class:`UnknownType`.
  Only packages registered as ROS interface packages (ament index ``rosidl_interfaces``) are
  imported: a type name never makes the bridge import an arbitrary module.
* :func:`dict_to_message` ``(cls, data)`` -> a new message; raises :class:`InvalidField`, whose
  text (safe to show a client) names the field path, its ROS type and the accepted values.
* :func:`message_to_dict` ``(message)`` -> a JSON-ready dict (NaN/Inf as null).

Every value is checked here, because rosidl's Python setters do not check in Jazzy (unless
``ROS_PYTHON_CHECK_FIELDS`` is set) and the C conversion then wraps or garbles what it gets:
``Int8`` 128 arrived as -128, ``UInt32`` 2**32 as 0, a ``double[9]`` of 2 values or a string
with a lone surrogate failed inside ``publish``.  Integers must be in their type's range,
``float32`` values in float32's, strings encodable and within their bound, fixed arrays of
their exact length and bounded sequences within their bound.

Encoding follows rosbridge 2.x: ``uint8[]``/``char[]`` as base64 (lists accepted on input),
times as ``{sec, nanosec}`` (``secs``/``nsecs`` and ``"now"`` accepted on input), NaN/Inf as
null (null read back as NaN), octets as ints.  Each message class gets a conversion *plan*
built once from ``get_fields_and_field_types()``.
"""

from __future__ import annotations

import base64
import binascii
import importlib
import math
import os
import re
import sys
import time
from collections.abc import Callable
from functools import cache
from pathlib import Path
from typing import Any

from .protocol import InvalidField, UnknownType, client_text, describe

_NAME = re.compile(r"/?([a-z][a-z0-9_]*)/(?:(msg|srv|action)/)?([A-Z][A-Za-z0-9_]*)\Z")
_INDEX = Path("share", "ament_index", "resource_index", "rosidl_interfaces")
_INT_RANGES = {
    "int8": (-(2**7), 2**7 - 1),
    "uint8": (0, 2**8 - 1),
    "int16": (-(2**15), 2**15 - 1),
    "uint16": (0, 2**16 - 1),
    "int32": (-(2**31), 2**31 - 1),
    "uint32": (0, 2**32 - 1),
    "int64": (-(2**63), 2**63 - 1),
    "uint64": (0, 2**64 - 1),
}
FLOAT32_MAX = 3.4028234663852886e38
_BINARY = {"uint8", "char"}
_TIME_TYPES = {"builtin_interfaces/Time", "builtin_interfaces/Duration"}
_TIME_ALIASES = {"secs": "sec", "nsecs": "nanosec"}

ToJson = Callable[[Any], Any]
FromJson = Callable[[Any, str], Any]


# --- types ---------------------------------------------------------------------------------------


@cache
def load_type(name: str, kind: str = "msg") -> Any:
    """The interface class for ``pkg/T`` or ``pkg/kind/T``; ``kind`` is msg, srv or action."""
    match = _NAME.match(name) if isinstance(name, str) else None
    if not match:
        raise UnknownType(f"{describe(name)} is not a {kind} type name (expected package/{kind}/Type or package/Type)")
    package, explicit_kind, type_name_ = match.groups()
    if explicit_kind and explicit_kind != kind:
        raise UnknownType(f"'{name}' is a {explicit_kind} type, but a {kind} type is needed here")
    if not is_interface_package(package):
        raise UnknownType(f"unknown {kind} type '{name}': no ROS interface package '{package}' is installed")
    try:
        module = importlib.import_module(f"{package}.{kind}")
        cls = getattr(module, type_name_)
    except (ImportError, AttributeError):
        raise UnknownType(f"unknown {kind} type '{name}': no {package}/{kind}/{type_name_} is installed") from None
    marker = {"msg": "get_fields_and_field_types", "srv": "Request", "action": "Goal"}[kind]
    if not hasattr(cls, marker):
        raise UnknownType(f"'{name}' is not a ROS {kind} type")
    return cls


def is_interface_package(package: str) -> bool:
    """Whether ``package`` is registered in an ament index as a ROS interface package (the
    venv's own prefix and those of ``AMENT_PREFIX_PATH``)."""
    prefixes = [p for p in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p] + [sys.prefix]
    return any((Path(prefix) / _INDEX / package).is_file() for prefix in prefixes)


def type_name(cls: Any) -> str:
    """The canonical ``pkg/kind/Type`` name of an interface class."""
    module = cls.__module__.split(".")
    return f"{module[0]}/{module[1]}/{cls.__name__}"


# --- messages ------------------------------------------------------------------------------------


def message_to_dict(message: Any) -> dict[str, Any]:
    """A JSON-ready dict of ``message``."""
    cls: Any = type(message)
    result: dict[str, Any] = _plan(cls)[0](message)
    return result


def dict_to_message(cls: Any, data: Any, path: str = "msg") -> Any:
    """A new ``cls`` instance filled from ``data`` (missing fields keep their defaults).

    Raises:
        InvalidField: a value does not fit its field (the text names path, type and range).
    """
    return _plan(cls)[1](data, path)


def list_to_request(cls: Any, values: list[Any], path: str = "args") -> Any:
    """A request filled from positional ``values`` in field order (rosbridge list args)."""
    fields = list(cls.get_fields_and_field_types())
    if len(values) > len(fields):
        raise InvalidField(f"{path}: {len(values)} values given, but {type_name(cls)} has {len(fields)} fields")
    return dict_to_message(cls, dict(zip(fields, values, strict=False)), path)


def field_types(cls: Any) -> dict[str, str]:
    """Field name -> rosidl type string, e.g. ``sequence<double, 3>`` (for message_details)."""
    return dict(cls.get_fields_and_field_types())


# --- plans ---------------------------------------------------------------------------------------


@cache
def _plan(cls: Any) -> tuple[Callable[[Any], dict[str, Any]], FromJson]:
    fields = [(name, *_field_converters(spec)) for name, spec in cls.get_fields_and_field_types().items()]
    names = {name for name, _, _ in fields}
    setters = {name: from_json for name, _, from_json in fields}
    is_time = type_name(cls).replace("/msg/", "/") in _TIME_TYPES
    is_header = type_name(cls) == "std_msgs/msg/Header"
    full_name = type_name(cls)

    def to_json(message: Any) -> dict[str, Any]:
        return {name: conv(getattr(message, name)) for name, conv, _ in fields}

    def from_json(data: Any, path: str) -> Any:
        if is_time and data == "now":
            now = time.time_ns()
            return cls(sec=now // 1_000_000_000, nanosec=now % 1_000_000_000)
        if not isinstance(data, dict):
            raise InvalidField(f"{path}: expected an object for {full_name}, got {describe(data)}")
        message = cls()
        for key, value in data.items():
            if is_time:
                key = _TIME_ALIASES.get(key, key)
            if key not in names:
                if is_header and key == "seq":  # ROS 1 clients (jrosbridge) still send it
                    continue
                raise InvalidField(
                    f"{path}: {full_name} has no field {client_text(key, 60)!r} (fields: {', '.join(sorted(names))})"
                )
            converted = setters[key](value, f"{path}.{key}")
            try:
                setattr(message, key, converted)
            except (AssertionError, TypeError, ValueError, OverflowError):
                raise InvalidField(f"{path}.{key}: {describe(value)} does not fit this field") from None
        return message

    return to_json, from_json


def _field_converters(spec: str) -> tuple[ToJson, FromJson]:
    """Converters of one field, from its rosidl type string: ``T``, ``T[N]`` (array),
    ``sequence<T>`` or ``sequence<T, N>`` (bounded), with T a primitive, ``string<=N`` or a message."""
    if spec.startswith("sequence<"):
        base, bound = spec[len("sequence<") : -1], None
        head, _, tail = base.rpartition(",")
        if head and tail.strip().isdigit():
            base, bound = head.strip(), int(tail)
        exact = False
    elif spec.endswith("]"):
        base, bound, exact = spec[: spec.index("[")], int(spec[spec.index("[") + 1 : -1]), True
    else:
        return _scalar_converters(spec)
    element_to, element_from = _scalar_converters(base)
    if base in _BINARY:
        # a fixed array's setter wants a sequence of ints (it makes a numpy array), a sequence's takes bytes
        return _binary_to_json, _sized(_binary_list_from_json if exact else _binary_from_json, spec, bound, exact)
    if base in ("float", "double"):
        return _float_list_to_json, _sized(_list_of(element_from), spec, bound, exact)
    if base in _INT_RANGES or base == "boolean":
        return _plain_list_to_json, _sized(_list_of(element_from), spec, bound, exact)

    def list_to_json(values: Any) -> list[Any]:
        return [element_to(v) for v in values]

    return list_to_json, _sized(_list_of(element_from), spec, bound, exact)


def _scalar_converters(base: str) -> tuple[ToJson, FromJson]:
    if base == "double":
        return _float_to_json, _double_from_json
    if base == "float":
        return _float_to_json, _float32_from_json
    if base in _INT_RANGES:
        return _identity, _int_from_json(base, *_INT_RANGES[base])
    if base == "boolean":
        return _identity, _bool_from_json
    if base == "octet":
        return _octet_to_json, _octet_from_json
    if base in ("char", "wchar"):
        return _identity, _char_from_json
    if base.startswith(("string", "wstring")):
        wide = base.startswith("wstring")
        bound = int(base.split("<=")[1]) if "<=" in base else None
        return _identity, _string_from_json(wide, bound)
    nested = load_type(base, "msg")
    to_json, from_json = _plan(nested)
    return to_json, from_json


def _sized(from_json: FromJson, spec: str, bound: int | None, exact: bool) -> FromJson:
    """``from_json`` checking the length of an array (exactly ``bound``) or a bounded sequence."""
    if bound is None:
        return from_json

    def checked(value: Any, path: str) -> Any:
        result = from_json(value, path)
        if (len(result) != bound) if exact else (len(result) > bound):
            need = f"exactly {bound}" if exact else f"at most {bound}"
            raise InvalidField(f"{path}: {spec} takes {need} elements, got {len(result)}")
        return result

    return checked


def _identity(value: Any) -> Any:
    return value


def _float_to_json(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _double_from_json(value: Any, path: str) -> float:
    if isinstance(value, float):
        return value
    if isinstance(value, int) and not isinstance(value, bool):
        try:
            return float(value)
        except OverflowError:
            raise InvalidField(f"{path}: {describe(value)} is out of the range of float64") from None
    if value is None:  # rosbridge sends NaN and Inf as null
        return math.nan
    raise InvalidField(f"{path}: expected a number (float64), got {describe(value)}")


def _float32_from_json(value: Any, path: str) -> float:
    number = _double_from_json(value, path)
    if math.isfinite(number) and abs(number) > FLOAT32_MAX:
        raise InvalidField(f"{path}: {describe(value)} is out of the range of float32 (±{FLOAT32_MAX:.7g})")
    return number


def _int_from_json(type_: str, low: int, high: int) -> FromJson:
    def from_json(value: Any, path: str) -> int:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise InvalidField(f"{path}: expected an integer ({type_}), got {describe(value)}")
        if isinstance(value, float):
            if not value.is_integer():
                raise InvalidField(f"{path}: expected an integer ({type_}), got {describe(value)}")
            value = int(value)
        if not low <= value <= high:
            raise InvalidField(f"{path}: {describe(value)} is out of the range of {type_} ({low} to {high})")
        return int(value)

    return from_json


def _bool_from_json(value: Any, path: str) -> bool:
    if isinstance(value, bool):
        return value
    raise InvalidField(f"{path}: expected true or false, got {describe(value)}")


def _string_from_json(wide: bool, bound: int | None) -> FromJson:
    kind = ("wstring" if wide else "string") + (f"<={bound}" if bound is not None else "")
    codec = "utf-16-le" if wide else "utf-8"
    unit = 2 if wide else 1

    def from_json(value: Any, path: str) -> str:
        if not isinstance(value, str):
            raise InvalidField(f"{path}: expected a string, got {describe(value)}")
        if value.isascii() and not wide:
            size = len(value)
        else:
            try:
                size = len(value.encode(codec)) // unit
            except UnicodeEncodeError:
                raise InvalidField(
                    f"{path}: the string holds characters {kind} cannot carry (a lone surrogate)"
                ) from None
        if bound is not None and size > bound:
            raise InvalidField(f"{path}: {kind} takes at most {bound} characters, got {size}")
        return value

    return from_json


def _char_from_json(value: Any, path: str) -> str:
    if isinstance(value, str) and len(value) == 1 and ord(value) < 0x10000 and not 0xD800 <= ord(value) < 0xE000:
        return value
    raise InvalidField(f"{path}: expected a single character, got {describe(value)}")


def _octet_to_json(value: Any) -> int:
    return int(value[0] if isinstance(value, bytes) else value)


def _octet_from_json(value: Any, path: str) -> bytes:
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 256:
        return bytes([value])
    raise InvalidField(f"{path}: expected an octet (0 to 255), got {describe(value)}")


def _binary_to_json(value: Any) -> str:
    return base64.b64encode(bytes(value)).decode("ascii")


def _binary_from_json(value: Any, path: str) -> bytes:
    if isinstance(value, str):
        try:
            return base64.b64decode(value, validate=True)
        except (binascii.Error, ValueError):
            raise InvalidField(f"{path}: expected base64 text or a list of 0 to 255, got invalid base64") from None
    if isinstance(value, list) and all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < 256 for v in value):
        return bytes(value)
    raise InvalidField(f"{path}: expected base64 text or a list of 0 to 255, got {describe(value)}")


def _binary_list_from_json(value: Any, path: str) -> list[int]:
    return list(_binary_from_json(value, path))


def _plain_list_to_json(values: Any) -> list[Any]:
    listed: list[Any] = values.tolist() if hasattr(values, "tolist") else list(values)
    return listed


def _float_list_to_json(values: Any) -> list[float | None]:
    listed = values.tolist() if hasattr(values, "tolist") else list(values)
    if all(map(math.isfinite, listed)):
        return listed
    return [v if math.isfinite(v) else None for v in listed]


def _list_of(element_from: FromJson) -> FromJson:
    def from_json(value: Any, path: str) -> list[Any]:
        if not isinstance(value, list):
            raise InvalidField(f"{path}: expected a list, got {describe(value)}")
        return [element_from(v, f"{path}[{i}]") for i, v in enumerate(value)]

    return from_json
