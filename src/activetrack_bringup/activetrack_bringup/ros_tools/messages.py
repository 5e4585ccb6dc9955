"""Messages of any type, by name, as plain data and YAML (what ``ros2 topic echo`` prints)."""

from __future__ import annotations

import array
import importlib

import numpy as np
import yaml

from activetrack_bringup.ros_tools.session import ToolError

_Dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def message_type(name: str):
    """The message class of a type name (``pkg/msg/Type`` or ``pkg/Type``), as rosidl's
    generated Python packages define it; ToolError when it is not installed here."""
    parts = name.split("/")
    if len(parts) == 2:
        parts = [parts[0], "msg", parts[1]]
    if len(parts) != 3 or not all(parts):
        raise ToolError(f"{name!r} is not a message type name (pkg/msg/Type)", 2)
    package, kind, cls = parts
    try:
        return getattr(importlib.import_module(f"{package}.{kind}"), cls)
    except (ImportError, AttributeError):
        raise ToolError(f"message type {name} is not installed here", 2) from None


def to_plain(value):
    """A message (or field value) as dicts, lists and scalars, fields in definition order."""
    if hasattr(value, "get_fields_and_field_types"):
        return {f: to_plain(getattr(value, f)) for f in value.get_fields_and_field_types()}
    if isinstance(value, bytes):  # a ``byte`` field, or a ``byte[]`` element
        return value[0] if len(value) == 1 else list(value)
    if isinstance(value, list | tuple | array.array | np.ndarray):
        return [to_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def field(data, path: str, type_name: str = "the message"):
    """The value at a dotted ``path`` (``header.stamp.sec``; list items by index) of plain
    data; ToolError naming the fields there are."""
    for part in path.split("."):
        if isinstance(data, dict) and part in data:
            data = data[part]
        elif isinstance(data, list) and part.isdigit() and int(part) < len(data):
            data = data[int(part)]
        else:
            there = list(data) if isinstance(data, dict) else f"{len(data)} items" if isinstance(
                data, list) else "a value"  # fmt: skip
            raise ToolError(f"--field {path}: {type_name} has no {part!r} (there: {there})", 2)
    return data


def to_yaml(data) -> str:
    """Block-style YAML, keys in field order (ros2's layout); a scalar as itself."""
    if not isinstance(data, dict | list):
        return str(data)
    text = yaml.dump(data, Dumper=_Dumper, default_flow_style=False, sort_keys=False, width=1e9)
    return text.rstrip("\n")
