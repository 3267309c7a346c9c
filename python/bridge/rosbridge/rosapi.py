"""The rosapi services clients rely on, answered by the bridge itself under ``/rosapi/``.

No rosapi node and no rosapi_msgs are needed: ``call_service`` to ``/rosapi/<name>`` is
served here from the bridge node's graph view, with the response shapes of rosapi_msgs
(rosbridge 2.x), e.g. ``topics`` -> ``{topics: [...], types: [...]}``.  Parameters
(``/node:param`` names) go through each node's standard rcl_interfaces parameter services.

rosapi shows only what the allow-lists let a client use: topic and service lists are filtered
by ``--topics-glob``/``--services-glob``, a query about a refused name is refused, parameters
are read under ``--params-glob`` and set only under ``--set-params-glob`` (none by default).
"""

from __future__ import annotations

import json
from collections.abc import Awaitable, Callable
from typing import Any

from rcl_interfaces.msg import ParameterType

from .conversion import field_types, load_type
from .names import ros_name
from .protocol import CONNECTION_STATS, InvalidField, client_text, require
from .security import AllowList, Policy
from .services import Services
from .topics import Topics

PREFIX = "/rosapi/"
DISTRO = "jazzy"

_PARAM_FIELDS = {
    ParameterType.PARAMETER_BOOL: "bool_value",
    ParameterType.PARAMETER_INTEGER: "integer_value",
    ParameterType.PARAMETER_DOUBLE: "double_value",
    ParameterType.PARAMETER_STRING: "string_value",
    ParameterType.PARAMETER_BYTE_ARRAY: "byte_array_value",
    ParameterType.PARAMETER_BOOL_ARRAY: "bool_array_value",
    ParameterType.PARAMETER_INTEGER_ARRAY: "integer_array_value",
    ParameterType.PARAMETER_DOUBLE_ARRAY: "double_array_value",
    ParameterType.PARAMETER_STRING_ARRAY: "string_array_value",
}


class Rosapi:
    """Graph, type, time and parameter queries in rosapi's request/response shapes."""

    def __init__(self, topics: Topics, services: Services, policy: Policy) -> None:
        self.topics = topics
        self.services = services
        self.policy = policy
        self.node = topics.node
        self._handlers: dict[str, Callable[[dict[str, Any]], Awaitable[dict[str, Any]]]] = {
            "topics": self._topics,
            "topics_for_type": self._topics_for_type,
            "topic_type": self._topic_type,
            "publishers": self._publishers,
            "subscribers": self._subscribers,
            "services": self._services,
            "service_type": self._service_type,
            "nodes": self._nodes,
            "message_details": self._message_details,
            "service_request_details": self._service_request_details,
            "service_response_details": self._service_response_details,
            "get_time": self._get_time,
            "get_ros_version": self._get_ros_version,
            "get_param": self._get_param,
            "set_param": self._set_param,
            "get_param_names": self._get_param_names,
            "has_param": self._has_param,
        }

    @staticmethod
    def serves(service: str) -> bool:
        return service.startswith(PREFIX)

    def names(self) -> list[str]:
        """The services the bridge answers itself (listed among the graph's services)."""
        return [PREFIX + name for name in self._handlers] + [CONNECTION_STATS]

    async def call(self, service: str, args: Any) -> dict[str, Any]:
        handler = self._handlers.get(service[len(PREFIX) :])
        if handler is None:
            raise InvalidField(f"Service {service} does not exist (rosapi here serves: {', '.join(self._handlers)})")
        if isinstance(args, list):
            raise InvalidField(f"{service} takes its args as an object")
        return await handler(args or {})

    # --- graph ---------------------------------------------------------------------------------
    def _allowed_topics(self) -> list[tuple[str, list[str]]]:
        return sorted(
            (name, types)
            for name, types in self.node.get_topic_names_and_types()
            if types and self.policy.topics.allows(name)
        )

    def _topic(self, args: dict[str, Any]) -> str:
        topic = ros_name("topic", require(args, "topic", str))
        self.policy.topics.check(topic)
        return topic

    async def _topics(self, args: dict[str, Any]) -> dict[str, Any]:
        pairs = self._allowed_topics()
        return {"topics": [p[0] for p in pairs], "types": [p[1][0] for p in pairs]}

    async def _topics_for_type(self, args: dict[str, Any]) -> dict[str, Any]:
        wanted = _canonical(require(args, "type", str), "msg")
        return {"topics": [name for name, types in self._allowed_topics() if wanted in types]}

    async def _topic_type(self, args: dict[str, Any]) -> dict[str, Any]:
        return {"type": self.topics.graph_type(self._topic(args)) or ""}

    async def _publishers(self, args: dict[str, Any]) -> dict[str, Any]:
        infos = self.node.get_publishers_info_by_topic(self._topic(args))
        return {"publishers": sorted(f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in infos)}

    async def _subscribers(self, args: dict[str, Any]) -> dict[str, Any]:
        infos = self.node.get_subscriptions_info_by_topic(self._topic(args))
        return {"subscribers": sorted(f"{i.node_namespace.rstrip('/')}/{i.node_name}" for i in infos)}

    async def _services(self, args: dict[str, Any]) -> dict[str, Any]:
        names = set(self.services.graph()) | set(self.names())
        return {"services": sorted(n for n in names if self.policy.services.allows(n))}

    async def _service_type(self, args: dict[str, Any]) -> dict[str, Any]:
        service = ros_name("service", require(args, "service", str))
        self.policy.services.check(service)
        return {"type": self.services.graph_type(service) or ""}

    async def _nodes(self, args: dict[str, Any]) -> dict[str, Any]:
        nodes = self.node.get_node_names_and_namespaces()
        return {"nodes": sorted(f"{ns.rstrip('/')}/{name}" for name, ns in nodes)}

    # --- types ---------------------------------------------------------------------------------
    async def _message_details(self, args: dict[str, Any]) -> dict[str, Any]:
        return {"typedefs": _typedefs(load_type(require(args, "type", str), "msg"))}

    async def _service_request_details(self, args: dict[str, Any]) -> dict[str, Any]:
        return {"typedefs": _typedefs(load_type(require(args, "type", str), "srv").Request)}

    async def _service_response_details(self, args: dict[str, Any]) -> dict[str, Any]:
        return {"typedefs": _typedefs(load_type(require(args, "type", str), "srv").Response)}

    # --- time and version ----------------------------------------------------------------------
    async def _get_time(self, args: dict[str, Any]) -> dict[str, Any]:
        now = self.node.get_clock().now().nanoseconds
        return {"time": {"sec": now // 1_000_000_000, "nanosec": now % 1_000_000_000}}

    async def _get_ros_version(self, args: dict[str, Any]) -> dict[str, Any]:
        return {"version": 2, "distro": DISTRO}

    # --- parameters ----------------------------------------------------------------------------
    async def _get_param(self, args: dict[str, Any]) -> dict[str, Any]:
        node, param = self._param(args, self.policy.params)
        reply = await self.services.call(f"{node}/get_parameters", {"names": [param]}, None)
        values = reply.get("values") or []
        if not values or values[0]["type"] == ParameterType.PARAMETER_NOT_SET:
            return {"value": args.get("default_value", "")}
        return {"value": json.dumps(values[0][_PARAM_FIELDS[values[0]["type"]]])}

    async def _has_param(self, args: dict[str, Any]) -> dict[str, Any]:
        node, param = self._param(args, self.policy.params)
        reply = await self.services.call(f"{node}/get_parameters", {"names": [param]}, None)
        values = reply.get("values") or []
        return {"exists": bool(values) and values[0]["type"] != ParameterType.PARAMETER_NOT_SET}

    async def _set_param(self, args: dict[str, Any]) -> dict[str, Any]:
        node, param = self._param(args, self.policy.set_params)
        try:
            value = json.loads(require(args, "value", str))
        except json.JSONDecodeError as exc:
            raise InvalidField(f"value must be JSON text ({exc})") from None
        reply = await self.services.call(f"{node}/set_parameters", {"parameters": [_parameter(param, value)]}, None)
        results = reply.get("results") or [{}]
        if not results[0].get("successful"):
            raise InvalidField(f"node {node} refused {param}={value!r}: {results[0].get('reason', '')}")
        return {}

    async def _get_param_names(self, args: dict[str, Any]) -> dict[str, Any]:
        names: list[str] = []
        for name, ns in self.node.get_node_names_and_namespaces():
            node = f"{ns.rstrip('/')}/{name}"
            if f"{node}/list_parameters" not in self.services.graph():
                continue
            reply = await self.services.call(f"{node}/list_parameters", {}, 2.0)
            names += [f"{node}:{p}" for p in reply["result"]["names"]]
        return {"names": sorted(n for n in names if self.policy.params.allows(n))}

    @staticmethod
    def _param(args: dict[str, Any], allowed: AllowList) -> tuple[str, str]:
        name = require(args, "name", str)
        node, param = _split_param(name)
        allowed.check(name)
        return node, param


def _canonical(name: str, kind: str) -> str:
    cls = load_type(name, kind)
    return f"{cls.__module__.split('.')[0]}/{kind}/{cls.__name__}"


def _split_param(name: str) -> tuple[str, str]:
    node, sep, param = name.partition(":")
    if not sep or not param or len(name) > 255:
        raise InvalidField(f"parameter name {client_text(name, 80)!r} must look like /node:param")
    return ros_name("node", node), param


def _parameter(name: str, value: Any) -> dict[str, Any]:
    kinds = [
        (bool, ParameterType.PARAMETER_BOOL),
        (int, ParameterType.PARAMETER_INTEGER),
        (float, ParameterType.PARAMETER_DOUBLE),
        (str, ParameterType.PARAMETER_STRING),
    ]
    for python_type, ros_type in kinds:
        if isinstance(value, python_type):
            return {"name": name, "value": {"type": ros_type, _PARAM_FIELDS[ros_type]: value}}
    if isinstance(value, list) and value:
        for python_type, ros_type in kinds:
            if all(isinstance(v, python_type) and (python_type is bool or not isinstance(v, bool)) for v in value):
                array_type = ros_type + 4  # the *_ARRAY types follow the scalar ones in rcl_interfaces
                return {"name": name, "value": {"type": array_type, _PARAM_FIELDS[array_type]: value}}
    raise InvalidField(f"parameter value {value!r} is not a bool, int, float, string or a list of one of them")


def _typedefs(cls: Any) -> list[dict[str, Any]]:
    """rosapi TypeDefs of ``cls`` and every message type nested in it, outermost first."""
    seen: dict[str, dict[str, Any]] = {}
    pending = [cls]
    while pending:
        current = pending.pop(0)
        name = f"{current.__module__.split('.')[0]}/msg/{current.__name__}".replace("_Request", "").replace(
            "_Response", ""
        )
        if name in seen:
            continue
        fields = field_types(current)
        typedef: dict[str, Any] = {
            "type": name,
            "fieldnames": [],
            "fieldtypes": [],
            "fieldarraylen": [],
            "examples": [],
            "constnames": [],
            "constvalues": [],
        }
        for field, spec in fields.items():
            base, array_len = _base_and_len(spec)
            typedef["fieldnames"].append(field)
            typedef["fieldtypes"].append(base)
            typedef["fieldarraylen"].append(array_len)
            typedef["examples"].append("{}" if "/" in base else ("[]" if array_len >= 0 else ""))
            if "/" in base:
                pending.append(load_type(base, "msg"))
        seen[name] = typedef
    return list(seen.values())


#: rosidl type names -> the ROS message-definition names rosapi reports
_IDL_NAMES = {"double": "float64", "float": "float32", "boolean": "bool", "octet": "byte"}


def _base_and_len(spec: str) -> tuple[str, int]:
    if spec.startswith("sequence<"):
        base, array_len = spec[len("sequence<") : -1].split(",")[0].strip(), 0
    elif spec.endswith("]"):
        base, array_len = spec[: spec.index("[")], int(spec[spec.index("[") + 1 : -1])
    else:
        base, array_len = spec, -1
    return _IDL_NAMES.get(base, base.split("<=")[0]), array_len
