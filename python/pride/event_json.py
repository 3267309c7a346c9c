"""How an event's payload becomes the JSON the audit log stores, and is read back from it.

The payload classes (:mod:`pride.event_payloads`) derive from :class:`Recorded`. The JSON is the
one the runs have always stored, key for key, so every stored hash and onboard chain stays valid:

- a field is written under its own name, or the one its metadata gives (``from_`` as ``from``);
- a field declared with :func:`optional` is left out while it has its default (a command sent
  once has no ``resend``); every other field is always written, ``null`` included;
- a payload read from stored JSON (:func:`read_payload`) writes back exactly the keys it was read
  with, in the values it was read with, and the keys this version does not know (``extra``): an
  older or newer run's record is kept as it was, never trimmed.

Stored JSON is input from outside (a database, a downlink): a value of the wrong type is refused
with :class:`EventDataError` naming the event kind, the field and the type expected; a field an
older run did not record yet reads as its default (or its type's empty value).
"""

from __future__ import annotations

import dataclasses
import types
import typing
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, ClassVar, TypeVar, Union

from pride.event_kinds import EventKind

__all__ = ["EventDataError", "Recorded", "optional", "read_payload"]

_OPTIONAL = "optional"  # field metadata: left out of the JSON while at its default
JSON_NAME = "json"  # field metadata: the key a field is stored under, when not its own name

_R = TypeVar("_R", bound="Recorded")


class EventDataError(ValueError):
    """A stored event's data does not fit its kind (a value of the wrong type, not an object)."""


def optional(default: Any = None) -> Any:
    """A field recorded only when it says something: left out of the JSON while at ``default``."""
    return field(default=default, metadata={_OPTIONAL: True})


@dataclass(frozen=True, kw_only=True)
class Recorded:
    """What every payload carries besides its fields: how it was stored, to write it back the same."""

    KIND: ClassVar[EventKind]

    extra: Mapping[str, Any] = field(default_factory=dict, repr=False)
    """Keys of stored data this version does not know (an older or newer run's): written back as they were."""
    stored: frozenset[str] | None = field(default=None, repr=False, compare=False)
    """The declared keys the stored JSON held (None: made by this version, see :meth:`to_json`)."""

    def _left_out(self) -> set[str]:
        """The fields a payload made now leaves out of its JSON: the optional ones at their default."""
        fields = _schema(type(self)).fields
        return {f.name for f, _, _ in fields if f.metadata.get(_OPTIONAL) and getattr(self, f.name) == f.default}

    def to_json(self) -> dict[str, Any]:
        """The event's ``data`` as stored (see the module docstring); sequences become lists."""
        left_out = self._left_out() if self.stored is None else set()
        data: dict[str, Any] = {}
        for f, key, _ in _schema(type(self)).fields:
            if self.stored is not None and key not in self.stored:
                continue
            if f.name in left_out:
                continue
            value = getattr(self, f.name)
            data[key] = list(value) if isinstance(value, tuple) else value
        data.update(self.extra)
        return data


@dataclass(frozen=True)
class _Schema:
    """What reading a payload class needs, worked out once per class: resolving its annotations
    (``typing.get_type_hints``) cost more than reading the event itself, and a console lists runs
    by reading every event of each."""

    fields: tuple[tuple[dataclasses.Field[Any], str, Any], ...]  # a field, its JSON key, its type
    keys: frozenset[str]


_SCHEMAS: dict[type, _Schema] = {}


def _schema(cls: type) -> _Schema:
    schema = _SCHEMAS.get(cls)
    if schema is None:
        hints = typing.get_type_hints(cls)
        declared = [f for f in dataclasses.fields(cls) if f.name not in ("extra", "stored")]
        fields = tuple((f, f.metadata.get(JSON_NAME, f.name), hints[f.name]) for f in declared)
        schema = _SCHEMAS[cls] = _Schema(fields, frozenset(key for _, key, _ in fields))
    return schema


def read_payload(cls: type[_R], data: object) -> _R:
    """Read a stored event's ``data`` (parsed JSON) into payload class ``cls``; see the module docstring.

    Raises:
        EventDataError: ``data`` is not an object, or a field's value is not of its type.
    """
    kind = cls.KIND
    if not isinstance(data, Mapping):
        raise EventDataError(f"{kind.value}: data must be an object, not {type(data).__name__}")
    schema = _schema(cls)
    values: dict[str, Any] = {}
    stored: set[str] = set()
    for f, key, hint in schema.fields:
        if key not in data:
            if f.default is dataclasses.MISSING:  # an older run's record: the field reads empty
                values[f.name] = _empty(hint)
            continue
        value = data[key]
        if not _fits(value, hint):
            raise EventDataError(
                f"{kind.value}: data.{key} must be {_describe(hint)}, not {type(value).__name__} ({str(value)[:60]!r})"
            )
        values[f.name] = tuple(value) if isinstance(value, list) and _is_sequence(hint) else value
        stored.add(key)
    extra = {k: v for k, v in data.items() if k not in schema.keys}
    return cls(**values, extra=extra, stored=frozenset(stored))


# ---- checking stored values against the declared types -----------------------------------------


def _members(hint: Any) -> tuple[Any, ...]:
    origin = typing.get_origin(hint)
    if origin is Union or origin is types.UnionType:
        return typing.get_args(hint)
    return (hint,)


def _is_sequence(hint: Any) -> bool:
    return any(typing.get_origin(m) is tuple for m in _members(hint))


def _fits(value: object, hint: Any) -> bool:
    for member in _members(hint):
        origin = typing.get_origin(member)
        if member is Any:
            return True
        if member is type(None):
            if value is None:
                return True
        elif origin is tuple:
            element = typing.get_args(member)[0]
            if isinstance(value, list) and all(_fits(v, element) for v in value):
                return True
        elif origin is Mapping or member is Mapping:
            if isinstance(value, Mapping):
                return True
        elif member is float:
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                return True
        elif member is int:
            if isinstance(value, int) and not isinstance(value, bool):
                return True
        elif isinstance(member, type) and isinstance(value, member):
            return True
    return False


def _empty(hint: Any) -> Any:
    members = _members(hint)
    if type(None) in members or Any in members:
        return None
    first = members[0]
    origin = typing.get_origin(first)
    if origin is tuple:
        return ()
    if origin is Mapping:
        return {}
    return {str: "", int: 0, float: 0.0, bool: False}[first]


def _describe(hint: Any) -> str:
    names = {str: "text", int: "an integer", float: "a number", bool: "true or false", type(None): "null"}
    parts = []
    for member in _members(hint):
        origin = typing.get_origin(member)
        if origin is tuple:
            parts.append(f"a list of {_describe(typing.get_args(member)[0])}")
        elif origin is Mapping:
            parts.append("an object")
        else:
            parts.append(names.get(member, str(member)))
    return " or ".join(parts)
