"""ROS messages <-> JSON-ready dicts for any installed interface, by rosidl introspection.

Type names load in both spellings (``std_msgs/String`` and ``std_msgs/msg/String``).  Each
message class gets a conversion *plan* built once from ``get_fields_and_field_types()``, so a
message is converted by walking a list of closures instead of re-parsing type strings.

Encoding follows rosbridge 2.x: ``uint8[]``/``char[]`` as base64 (lists accepted on input),
times as ``{sec, nanosec}`` (``secs``/``nsecs`` accepted on input), NaN/Inf as null, octets
as ints.  Bad input raises :class:`InvalidField` naming the field path and the expected type.
"""

from __future__ import annotations

import base64
import importlib
import math
import re
import time
from functools import lru_cache
from typing import Any, Callable

from .protocol import InvalidField, UnknownType

_NAME = re.compile(r"^/?([a-z][a-z0-9_]*)/(?:(msg|srv|action)/)?([A-Z][A-Za-z0-9_]*)$")
_FLOATS = {"float", "double", "long double", "float32", "float64"}
_INTS = {"int8", "int16", "int32", "int64", "uint8", "uint16", "uint32", "uint64", "char", "wchar", "short",
         "unsigned short", "long", "unsigned long", "long long", "unsigned long long"}
_BINARY = {"uint8", "char"}
_TIME_TYPES = {"builtin_interfaces/Time", "builtin_interfaces/Duration"}
_TIME_ALIASES = {"secs": "sec", "nsecs": "nanosec"}

ToJson = Callable[[Any], Any]
FromJson = Callable[[Any, str], Any]


@lru_cache(maxsize=None)
def load_type(name: str, kind: str = "msg") -> Any:
    """The interface class for ``pkg/T`` or ``pkg/kind/T``; ``kind`` is msg, srv or action."""
    match = _NAME.match(name) if isinstance(name, str) else None
    if not match:
        raise UnknownType(f"'{name}' is not a {kind} type name (expected package/{kind}/Type or package/Type)")
    package, explicit_kind, type_name = match.groups()
    if explicit_kind and explicit_kind != kind:
        raise UnknownType(f"'{name}' is a {explicit_kind} type, but a {kind} type is needed here")
    try:
        module = importlib.import_module(f"{package}.{kind}")
        cls = getattr(module, type_name)
    except (ImportError, AttributeError):
        raise UnknownType(f"unknown {kind} type '{name}': no {package}/{kind}/{type_name} is installed") from None
    marker = {"msg": "get_fields_and_field_types", "srv": "Request", "action": "Goal"}[kind]
    if not hasattr(cls, marker):
        raise UnknownType(f"'{name}' is not a ROS {kind} type")
    return cls


def type_name(cls: Any) -> str:
    """The canonical ``pkg/kind/Type`` name of an interface class."""
    module = cls.__module__.split(".")
    return f"{module[0]}/{module[1]}/{cls.__name__}"


def message_to_dict(message: Any) -> dict[str, Any]:
    """A JSON-ready dict of ``message``."""
    return _plan(type(message))[0](message)


def dict_to_message(cls: Any, data: Any, path: str = "msg") -> Any:
    """A new ``cls`` instance filled from ``data`` (missing fields keep their defaults)."""
    return _plan(cls)[1](data, path)


def list_to_request(cls: Any, values: list[Any], path: str = "args") -> Any:
    """A request filled from positional ``values`` in field order (rosbridge list args)."""
    fields = list(cls.get_fields_and_field_types())
    if len(values) > len(fields):
        raise InvalidField(f"{path}: {len(values)} values given, but {type_name(cls)} has {len(fields)} fields")
    return dict_to_message(cls, dict(zip(fields, values)), path)


def field_types(cls: Any) -> dict[str, str]:
    """Field name -> rosidl type string, e.g. ``sequence<double, 3>`` (for message_details)."""
    return dict(cls.get_fields_and_field_types())


# --- plans ---------------------------------------------------------------------------------------

@lru_cache(maxsize=None)
def _plan(cls: Any) -> tuple[Callable[[Any], dict[str, Any]], FromJson]:
    fields = [(name, *_field_converters(spec)) for name, spec in cls.get_fields_and_field_types().items()]
    names = {name for name, _, _ in fields}
    setters = {name: from_json for name, _, from_json in fields}
    is_time = type_name(cls).replace("/msg/", "/") in _TIME_TYPES
    is_header = type_name(cls) == "std_msgs/msg/Header"

    def to_json(message: Any) -> dict[str, Any]:
        return {name: conv(getattr(message, name)) for name, conv, _ in fields}

    def from_json(data: Any, path: str) -> Any:
        if is_time and data == "now":
            now = time.time_ns()
            return cls(sec=now // 1_000_000_000, nanosec=now % 1_000_000_000)
        if not isinstance(data, dict):
            raise InvalidField(f"{path}: expected an object for {type_name(cls)}, got {_describe(data)}")
        message = cls()
        for key, value in data.items():
            if is_time:
                key = _TIME_ALIASES.get(key, key)
            if key not in names:
                if is_header and key == "seq":  # ROS 1 clients (jrosbridge) still send it
                    continue
                raise InvalidField(f"{path}: {type_name(cls)} has no field '{key}' (fields: {', '.join(sorted(names))})")
            converted = setters[key](value, f"{path}.{key}")
            try:
                setattr(message, key, converted)
            except (AssertionError, TypeError, ValueError) as exc:
                raise InvalidField(f"{path}.{key}: {_describe(value)} does not fit this field ({exc})") from None
        return message

    return to_json, from_json


def _field_converters(spec: str) -> tuple[ToJson, FromJson]:
    sequence = spec.startswith("sequence<")
    array = spec.endswith("]")
    if sequence:
        base = spec[len("sequence<"):-1]
        if base.rsplit(",", 1)[-1].strip().isdigit():  # bounded: sequence<T, N>
            base = base.rsplit(",", 1)[0].strip()
    elif array:
        base = spec[: spec.index("[")]
    else:
        base = spec
    element_to, element_from = _scalar_converters(base)
    if not (sequence or array):
        return element_to, element_from
    if base in _BINARY:
        return _binary_to_json, _binary_from_json
    if base in _FLOATS:
        return _float_list_to_json, _float_list_from_json
    if base in _INTS or base in ("boolean", "bool"):
        return _plain_list_to_json, _list_of(element_from)

    def list_to_json(values: Any) -> list[Any]:
        return [element_to(v) for v in values]

    return list_to_json, _list_of(element_from)


def _scalar_converters(base: str) -> tuple[ToJson, FromJson]:
    if base in _FLOATS:
        return _float_to_json, _float_from_json
    if base in _INTS:
        return _identity, _int_from_json
    if base in ("boolean", "bool"):
        return _identity, _bool_from_json
    if base in ("octet", "byte"):
        return _octet_to_json, _octet_from_json
    if base.startswith(("string", "wstring")):
        return _identity, _string_from_json
    nested = load_type(base, "msg")
    to_json, from_json = _plan(nested)
    return to_json, from_json


def _identity(value: Any) -> Any:
    return value


def _describe(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) < 50 else text[:47] + '...'}"


def _float_to_json(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _float_from_json(value: Any, path: str) -> float:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return float(value)
    if value is None:
        return math.nan
    raise InvalidField(f"{path}: expected a number, got {_describe(value)}")


def _int_from_json(value: Any, path: str) -> int:
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, float) and value.is_integer():
        return int(value)
    raise InvalidField(f"{path}: expected an integer, got {_describe(value)}")


def _bool_from_json(value: Any, path: str) -> bool:
    if isinstance(value, bool):
        return value
    raise InvalidField(f"{path}: expected true or false, got {_describe(value)}")


def _string_from_json(value: Any, path: str) -> str:
    if isinstance(value, str):
        return value
    raise InvalidField(f"{path}: expected a string, got {_describe(value)}")


def _octet_to_json(value: bytes) -> int:
    return value[0] if isinstance(value, bytes) else int(value)


def _octet_from_json(value: Any, path: str) -> bytes:
    if isinstance(value, int) and not isinstance(value, bool) and 0 <= value < 256:
        return bytes([value])
    raise InvalidField(f"{path}: expected an octet (0..255), got {_describe(value)}")


def _binary_to_json(value: Any) -> str:
    return base64.b64encode(bytes(value)).decode("ascii")


def _binary_from_json(value: Any, path: str) -> bytes:
    if isinstance(value, str):
        try:
            return base64.b64decode(value, validate=True)
        except ValueError:
            raise InvalidField(f"{path}: expected base64 text or a list of 0..255, got invalid base64") from None
    if isinstance(value, list) and all(isinstance(v, int) and not isinstance(v, bool) and 0 <= v < 256 for v in value):
        return bytes(value)
    raise InvalidField(f"{path}: expected base64 text or a list of 0..255, got {_describe(value)}")


def _plain_list_to_json(values: Any) -> list[Any]:
    return values.tolist() if hasattr(values, "tolist") else list(values)


def _float_list_to_json(values: Any) -> list[float | None]:
    listed = values.tolist() if hasattr(values, "tolist") else list(values)
    if all(map(math.isfinite, listed)):
        return listed
    return [v if math.isfinite(v) else None for v in listed]


def _float_list_from_json(value: Any, path: str) -> list[float]:
    if not isinstance(value, list):
        raise InvalidField(f"{path}: expected a list of numbers, got {_describe(value)}")
    return [_float_from_json(v, f"{path}[{i}]") for i, v in enumerate(value)]


def _list_of(element_from: FromJson) -> FromJson:
    def from_json(value: Any, path: str) -> list[Any]:
        if not isinstance(value, list):
            raise InvalidField(f"{path}: expected a list, got {_describe(value)}")
        return [element_from(v, f"{path}[{i}]") for i, v in enumerate(value)]

    return from_json
