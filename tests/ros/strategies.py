"""Hypothesis strategies for any ROS message type, built from its field types."""

from __future__ import annotations

import importlib

from hypothesis import strategies as st

FLOATS = st.one_of(
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, 5.0, 1e300, -1e300, 5e-324]),
)
UINT32 = st.one_of(st.integers(0, 2**32 - 1), st.sampled_from([0, 1, 2, 3, 8, 9]))
INT32 = st.integers(-(2**31), 2**31 - 1)
INT64 = st.one_of(st.integers(-(2**63), 2**63 - 1), st.sampled_from([-2, -1, 0, 1, 3]))
UINT8 = st.one_of(st.integers(0, 255), st.sampled_from([0, 1, 2]))
TEXT = st.one_of(
    st.text(max_size=20), st.sampled_from(["s1", "s2", "p1", "p2", "pf", "ekf", "x", "y"])
)


def _class(name: str):
    package, msg = name.split("/")
    return getattr(importlib.import_module(f"{package}.msg"), msg)


def field(kind: str, depth: int):
    if kind == "double":
        return FLOATS
    if kind == "uint32":
        return UINT32
    if kind == "int32":
        return INT32
    if kind == "int64":
        return INT64
    if kind == "uint8":
        return UINT8
    if kind == "boolean":
        return st.booleans()
    if kind == "octet":
        return st.binary(min_size=1, max_size=1)
    if kind == "string":
        return TEXT
    if kind.startswith("uint8[") and kind.endswith("]"):
        n = int(kind[6:-1])
        return st.lists(st.integers(0, 255), min_size=n, max_size=n)
    if kind.startswith("double[") and kind.endswith("]"):
        n = int(kind[7:-1])
        return st.lists(FLOATS, min_size=n, max_size=n)
    if kind.startswith("sequence<"):
        inner = kind[len("sequence<") : -1]
        # Long primitive arrays at the top; a few nested messages (each costs a whole draw).
        size = 3 if depth else (4 if "/" in inner else 40)
        return st.lists(field(inner, depth + 1), max_size=size)
    return message(_class(kind), depth + 1)


def message(msg_type, depth: int = 0):
    """Every field drawn independently: NaN, inf, huge, negative stamps, odd lengths."""
    fields = {
        name: field(kind, depth) for name, kind in msg_type.get_fields_and_field_types().items()
    }
    return st.fixed_dictionaries(fields).map(lambda values: msg_type(**values))
