"""``activetrack ros param list|describe|get|set|dump``: a node's parameters through its
parameter services (what ``ros2 param`` calls), printed as ``ros2 param`` prints them; ``dump``
is a params file (``--params-file`` takes it back)."""

from __future__ import annotations

from collections.abc import Callable

import yaml
from rcl_interfaces.msg import ParameterType
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.parameter_client import AsyncParameterClient

from activetrack_bringup.ros_tools.messages import to_yaml
from activetrack_bringup.ros_tools.session import ToolError, ToolSession

TYPE_NAMES = {
    ParameterType.PARAMETER_NOT_SET: "not set",
    ParameterType.PARAMETER_BOOL: "boolean",
    ParameterType.PARAMETER_INTEGER: "integer",
    ParameterType.PARAMETER_DOUBLE: "double",
    ParameterType.PARAMETER_STRING: "string",
    ParameterType.PARAMETER_BYTE_ARRAY: "byte array",
    ParameterType.PARAMETER_BOOL_ARRAY: "boolean array",
    ParameterType.PARAMETER_INTEGER_ARRAY: "integer array",
    ParameterType.PARAMETER_DOUBLE_ARRAY: "double array",
    ParameterType.PARAMETER_STRING_ARRAY: "string array",
}
# ``ros2 param get``'s words: "Double value is: 2.0".
VALUE_WORDS = {
    ParameterType.PARAMETER_BOOL: "Boolean",
    ParameterType.PARAMETER_INTEGER: "Integer",
    ParameterType.PARAMETER_DOUBLE: "Double",
    ParameterType.PARAMETER_STRING: "String",
}


class ParamTool:
    """Parameter service calls on nodes of a session's graph (relative names in its
    namespace), each within ``timeout`` seconds (ToolError naming the node otherwise)."""

    def __init__(self, session: ToolSession, timeout: float):
        self.session = session
        self.timeout = timeout
        self._clients: dict[str, AsyncParameterClient] = {}

    def client(self, node: str) -> tuple[str, AsyncParameterClient]:
        name = self.session.resolve_node(node)
        if name not in self._clients:
            client = AsyncParameterClient(self.session.node, name)
            if not self.session.spin_until(client.services_are_ready, self.timeout):
                raise ToolError(
                    f"node {name} answers no parameter services within {self.timeout:g} s "
                    "(is it on this domain and namespace? --domain, --namespace)"
                )
            self._clients[name] = client
        return name, self._clients[name]

    def call(self, node: str, request: Callable):
        name, client = self.client(node)
        future = request(client)
        if not self.session.spin_until(future.done, self.timeout):
            raise ToolError(f"node {name} did not answer within {self.timeout:g} s")
        return future.result()

    def names(self, node: str) -> list[str]:
        return sorted(self.call(node, lambda c: c.list_parameters()).result.names)

    def values(self, node: str, names: list[str]) -> dict:
        """name -> ParameterValue message; ToolError for a name the node does not have."""
        reply = self.call(node, lambda c: c.get_parameters(names)).values
        if len(reply) != len(names) or any(
            v.type == ParameterType.PARAMETER_NOT_SET for v in reply
        ):
            # rclpy answers an unknown name with no values at all: say which names
            have = set(self.names(node))
            missing = [n for n in names if n not in have]
            raise ToolError(f"{self.session.resolve_node(node)} has no parameter {missing}", 2)
        return dict(zip(names, reply, strict=True))

    def describe(self, node: str, names: list[str]) -> list:
        self.values(node, names)  # a name the node lacks: a clear error, not an empty reply
        return self.call(node, lambda c: c.describe_parameters(names)).descriptors

    def set(self, node: str, name: str, text: str):
        """Set from text as ``ros2 param set`` reads it (YAML: ``5`` an integer, ``5.0`` a
        double, ``true`` a boolean); returns the SetParametersResult."""
        value = yaml.safe_load(text) if text.strip() else ""
        if value is None:
            value = text
        try:
            param = Parameter(name, value=value)
        except TypeError:
            raise ToolError(f"cannot set {name} to {text!r}: not a parameter value", 2) from None
        return self.call(node, lambda c: c.set_parameters([param])).results[0]


def list_text(tool: ParamTool, nodes: list[str], services: set[str] | None = None) -> str:
    """Each node's parameter names; with ``services`` (the graph's service names) a node that
    offers no parameter services says so instead of timing out."""
    lines = []
    for node in nodes:
        name = tool.session.resolve_node(node)
        lines.append(f"{name}:")
        if services is not None and f"{name}/list_parameters" not in services:
            lines.append("  (answers no parameter services)")
            continue
        lines += [f"  {n}" for n in tool.names(node)]
    return "\n".join(lines)


def describe_text(descriptors) -> str:
    """Each descriptor as ``ros2 param describe`` prints it."""
    lines = []
    for d in descriptors:
        lines += [
            f"Parameter name: {d.name}",
            f"  Type: {TYPE_NAMES.get(d.type, d.type)}",
            f"  Description: {d.description}",
            "  Constraints:",
        ]
        if d.read_only:
            lines.append("    Read only: true")
        for r in d.floating_point_range:
            lines += [f"    Min value: {r.from_value}", f"    Max value: {r.to_value}"]
        for r in d.integer_range:
            lines += [f"    Min value: {r.from_value}", f"    Max value: {r.to_value}"]
            if r.step:
                lines.append(f"    Step: {r.step}")
        if d.additional_constraints:
            lines.append(f"    {d.additional_constraints}")
    return "\n".join(lines)


def get_text(value) -> str:
    words = VALUE_WORDS.get(value.type)
    python = parameter_value_to_python(value)
    if words is None:
        return f"{TYPE_NAMES.get(value.type, value.type).capitalize()} values are: {python}"
    return f"{words} value is: {python}"


def dump_yaml(tool: ParamTool, node: str) -> str:
    """The node's parameters as a params file (``ros2 param dump``'s layout)."""
    names = tool.names(node)
    values = tool.values(node, names) if names else {}
    params = {n: parameter_value_to_python(v) for n, v in values.items()}
    for n, v in params.items():  # arrays as plain lists
        if not isinstance(v, str | bool | int | float):
            params[n] = list(v)
    return to_yaml({tool.session.resolve_node(node): {"ros__parameters": params}})


def service_names(session: ToolSession) -> set[str]:
    return {name for name, _ in session.node.get_service_names_and_types()}
