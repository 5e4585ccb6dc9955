"""The graph's writer authentication and the node base's guards, piece by piece."""

import os
import subprocess
import sys

import pytest
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from message_examples import MESSAGE_TYPES, example_messages
from rclpy.serialization import deserialize_message, serialize_message

from activetrack_bringup.interrupts import Terminated
from activetrack_ros.convert import header
from activetrack_ros.node_base import GraphNode, RateLimitedLog, Rejected
from activetrack_ros.trust import AUTH_SIZE, KEY_ENV, GraphKey, is_signed_type

pytestmark = pytest.mark.ros
KEY = GraphKey(bytes(range(32)))
OTHER = GraphKey(bytes(range(1, 33)))


@pytest.mark.parametrize("msg", example_messages(), ids=lambda m: type(m).__name__)
def test_a_signed_message_verifies_and_any_change_breaks_it(msg):
    data = KEY.sign(serialize_message(msg))
    assert KEY.verify(data)
    assert not OTHER.verify(data)
    assert deserialize_message(data, type(msg)).header == msg.header  # still a valid message
    for i in range(0, len(data), 7):  # every 7th byte flipped, the trailer included
        flipped = bytearray(data)
        flipped[i] ^= 0x40
        assert not KEY.verify(bytes(flipped)), f"byte {i} of {len(data)}"
    assert not KEY.verify(data[:-1]) and not KEY.verify(data[: AUTH_SIZE + 4])


def test_dds_padding_between_processes_is_tolerated():
    # Between processes Fast DDS pads a payload to a multiple of 4 bytes (measured: 126 -> 128).
    data = KEY.sign(serialize_message(example_messages()[0]))
    for pad in (b"\0", b"\0\0", b"\0\0\0", b"\x7f\x01"):
        assert KEY.verify(data + pad)
    assert not KEY.verify(data + b"\0\0\0\0")  # four is not padding


def test_every_graph_type_carries_the_trailer_and_standard_types_do_not():
    assert all(is_signed_type(t) for t in MESSAGE_TYPES)
    assert not is_signed_type(DiagnosticArray)


def _diag(values):
    status = DiagnosticStatus(name="activetrack/sim_node", message="epoch 3/8", values=values)
    return DiagnosticArray(header=header(15.0), status=[status])


def test_diagnostics_tag_survives_reserialisation_and_catches_edits():
    array = KEY.sign_diagnostics(_diag([KeyValue(key="updates", value="3")]))
    back = deserialize_message(serialize_message(array), DiagnosticArray)
    assert KEY.verify_diagnostics(back) and not OTHER.verify_diagnostics(back)
    back.status[0].values[0].value = "4"
    assert not KEY.verify_diagnostics(back)
    # What ordinary ROS diagnostics drivers publish: no tag at all.
    assert not KEY.verify_diagnostics(_diag([KeyValue(key="temperature", value="41.5 C")]))


def test_key_from_the_environment():
    assert GraphKey.from_environment({}) is None
    key = GraphKey.from_environment({KEY_ENV: KEY.hex()})
    assert key.verify(KEY.sign(serialize_message(example_messages()[1])))
    with pytest.raises(ValueError, match=KEY_ENV):
        GraphKey.from_environment({KEY_ENV: "not hex"})
    with pytest.raises(ValueError, match="16..64 bytes"):
        GraphKey(b"short")


def test_rate_limited_log_keeps_counting_but_writes_one_line_per_second():
    lines = []

    class Logger:
        def warning(self, text):
            lines.append(text)

    log = RateLimitedLog(Logger(), interval=3600.0)
    for i in range(1000):
        log("warning", "rejected.non_finite", f"rejected {i}")
    log("warning", "rejected.bad_stamp", "other reason")
    assert lines == ["rejected 0", "other reason"]
    log.interval = 0.0
    log("warning", "rejected.non_finite", "again")
    assert lines[-1] == "again (and 999 more like it in the last 0 s)"


def test_guard_counts_rejections_and_errors_but_lets_signals_through(graph):
    node = graph.add(GraphNode("guarded", context=graph.context, graph_key=KEY))

    def bad_input():
        raise Rejected("non_finite", "x")

    def bug():
        return {}["missing"]

    node.guarded(bad_input)
    node.guarded(bug)
    node.guarded(bug)
    assert node.counters.counts["rejected.non_finite"] == 1
    assert node.counters.counts["errors.bug"] == 2
    for signal_exc in (KeyboardInterrupt, Terminated):

        def interrupted(exc=signal_exc):
            raise exc()

        with pytest.raises(signal_exc):
            node.guarded(interrupted)


def test_pypi_fast_dds_has_no_security_plugins(tmp_path):
    """What the README says about SROS2: enforcing a security enclave fails at node creation
    with these wheels. If a future wheel ships the plugins this test fails: then wire up
    `--secure` (see the README's trust section)."""
    enclave = tmp_path / "keystore" / "enclaves" / "probe"
    enclave.mkdir(parents=True)
    for name in (
        "identity_ca.cert.pem",
        "cert.pem",
        "key.pem",
        "permissions_ca.cert.pem",
        "governance.p7s",
        "permissions.p7s",
    ):
        (enclave / name).write_text("placeholder\n")
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    env.update(
        ROS_SECURITY_ENABLE="true",
        ROS_SECURITY_STRATEGY="Enforce",
        ROS_SECURITY_KEYSTORE=str(tmp_path / "keystore"),
    )
    code = (
        "import rclpy\n"
        "rclpy.init(args=['--ros-args', '--enclave', '/probe'])\n"
        "try:\n"
        "    rclpy.create_node('probe')\n"
        "    print('SECURE NODE CREATED')\n"
        "except Exception as exc:\n"
        "    print('REFUSED', exc)\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=60
    )
    assert "REFUSED" in out.stdout, out.stdout + out.stderr
    assert "doesn't have the security libraries" in out.stdout
