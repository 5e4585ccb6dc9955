"""Every msgs_defs type travels between two in-process nodes with every field intact."""

import math

import numpy as np
import pytest
from message_examples import MESSAGE_TYPES, example_messages
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message

from msgs_defs.msg import TrackItem

EXAMPLES = example_messages()


def _message_list(value) -> bool:
    return isinstance(value, list) and bool(value) and hasattr(value[0], "__slots__")


def _flatten(msg, prefix=""):
    """Yield (field path, leaf value) for every field of a message, recursively: into nested
    messages, and into sequences of messages item by item (the sequence itself yields its
    length)."""
    for name in msg.get_fields_and_field_types():
        value = getattr(msg, name)
        if hasattr(value, "get_fields_and_field_types"):
            yield from _flatten(value, f"{prefix}{name}.")
        elif _message_list(value):
            yield f"{prefix}{name}", len(value)
            for i, item in enumerate(value):
                yield from _flatten(item, f"{prefix}{name}.{i}.")
        else:
            yield f"{prefix}{name}", value


def _default(msg, path: str):
    """The field at ``path`` in a fresh instance of its owner's type (a sequence of messages:
    its length, 0)."""
    *parents, leaf = path.split(".")
    owner = msg
    for p in parents:
        owner = owner[int(p)] if p.isdigit() else getattr(owner, p)
    if _message_list(getattr(owner, leaf)):
        return 0
    return getattr(type(owner)(), leaf)


def test_examples_cover_every_type_with_non_default_fields():
    assert [type(m) for m in EXAMPLES] == list(MESSAGE_TYPES)
    for msg in EXAMPLES:
        for path, value in _flatten(msg):
            # A field left at its default could be dropped in transport unnoticed.
            default = _default(msg, path)
            if isinstance(value, np.ndarray):
                same = np.array_equal(value, default)
            else:
                same = value == default
            assert not same, f"{type(msg).__name__}.{path} is left at its default"
    # The track array's item is an example too: every field of TrackItem is filled.
    items = [path for m in EXAMPLES for path, _ in _flatten(m) if path.startswith("tracks.0.")]
    assert len(items) == len(TrackItem.get_fields_and_field_types())


@pytest.mark.parametrize("msg", EXAMPLES, ids=lambda m: type(m).__name__)
def test_serialization_round_trip(msg):
    back = deserialize_message(serialize_message(msg), type(msg))
    assert back == msg


@pytest.mark.ros
def test_every_type_between_two_nodes(graph):
    talker = graph.add(Node("talker", context=graph.context))
    listener = graph.add(Node("listener", context=graph.context))
    received = {}
    pubs = {}
    for msg in EXAMPLES:
        name = type(msg).__name__
        topic = f"/roundtrip/{name}"
        pubs[name] = talker.create_publisher(type(msg), topic, 10)
        listener.create_subscription(
            type(msg), topic, lambda m, n=name: received.setdefault(n, m), 10
        )

    def all_received():
        for msg in EXAMPLES:
            name = type(msg).__name__
            if name not in received:
                pubs[name].publish(msg)
        return len(received) == len(EXAMPLES)

    assert graph.spin_until(all_received, timeout=10.0), f"missing: {set(pubs) - set(received)}"
    for msg in EXAMPLES:
        got = received[type(msg).__name__]
        for (path, sent), (_, back) in zip(_flatten(msg), _flatten(got), strict=True):
            if isinstance(sent, float):
                assert math.isclose(back, sent, rel_tol=0, abs_tol=0), path
            else:
                assert list(back) == list(sent) if hasattr(sent, "__len__") else back == sent, path
        assert got == msg
