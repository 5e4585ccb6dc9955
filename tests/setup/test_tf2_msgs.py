"""tf2_msgs, built by tools/setup.sh from interfaces/tf2_msgs (no ros-jazzy-tf2-msgs wheel on
PyPI), is the ROS 2 Jazzy tf2_msgs on the wire.

The installed RIHS01 type hashes (rosidl's type description files) equal those of the official
Jazzy definitions as known to rosbags: same fields, types and nested types, so the same CDR
encoding and the same type identity for DDS and rosbag2. A TFMessage serialized by rclpy also
decodes with rosbags' Jazzy definition. RIHS01 leaves constants out, so TF2Error's are
compared on their own.
"""

from __future__ import annotations

import pytest
from geometry_msgs.msg import TransformStamped
from rclpy.serialization import deserialize_message, serialize_message
from rosbags.typesys import Stores, get_typestore
from tf2_msgs.msg import TF2Error, TFMessage

from activetrack_bringup.bag import installed_type_hash

TYPES = ("tf2_msgs/msg/TFMessage", "tf2_msgs/msg/TF2Error")


@pytest.fixture(scope="module")
def jazzy():
    return get_typestore(Stores.ROS2_JAZZY)


def _transform(child: str, x: float, sec: int):
    t = TransformStamped()
    t.header.stamp.sec = sec
    t.header.stamp.nanosec = 250_000_000
    t.header.frame_id = "map"
    t.child_frame_id = child
    t.transform.translation.x = x
    t.transform.translation.y = -2.5
    t.transform.rotation.z = 0.6
    t.transform.rotation.w = 0.8
    return t


def _two_transforms():
    return TFMessage(transforms=[_transform("platform", 1.5, 12), _transform("target", 40.0, 13)])


def test_tfmessage_imports():
    assert TFMessage().transforms == []
    assert TF2Error().error == TF2Error.NO_ERROR


def test_tfmessage_round_trips_through_rclpy_serialization():
    msg = _two_transforms()
    back = deserialize_message(serialize_message(msg), TFMessage)
    assert back == msg
    assert [t.child_frame_id for t in back.transforms] == ["platform", "target"]


def test_rclpy_bytes_decode_with_the_jazzy_definition(jazzy):
    decoded = jazzy.deserialize_cdr(serialize_message(_two_transforms()), TYPES[0])
    assert [t.child_frame_id for t in decoded.transforms] == ["platform", "target"]
    assert [t.transform.translation.x for t in decoded.transforms] == [1.5, 40.0]
    assert [t.header.stamp.sec for t in decoded.transforms] == [12, 13]
    assert decoded.transforms[1].transform.rotation.w == 0.8


@pytest.mark.parametrize("msgtype", TYPES)
def test_installed_type_hash_is_the_jazzy_one(msgtype, jazzy):
    installed = installed_type_hash(msgtype)
    assert installed is not None, f"no installed type description for {msgtype}"
    assert installed == jazzy.hash_rihs01(msgtype)


def test_tf2error_constants_are_the_jazzy_ones(jazzy):
    constants, _ = jazzy.fielddefs[TYPES[1]]
    assert constants, "rosbags knows TF2Error's constants"
    for name, _type, value in constants:
        assert getattr(TF2Error, name) == value, name
