"""Which writers count: the graph's own, recognised by a per-run key (docs/robustness.md).

Anyone on a shared DDS domain may publish on our topics, rclpy does not tell a callback the
writer (no publisher GID) and the PyPI wheels' Fast DDS has no security plugins. So every
msgs_defs message ends with ``graph_auth``, a 16-byte keyed BLAKE2b hash of the serialised bytes
before it, under a key made fresh for each run and handed to the nodes out of band (never a ROS
parameter, which other nodes could read); ``/diagnostics`` carries it in a key-value pair. A
message that does not verify is counted and dropped before it is deserialised. This stops
cross-talk and forged data from writers without the key; it does not hide the topics or stop a
flood from costing CPU.
"""

from __future__ import annotations

import hashlib
import hmac
import json
import os
import secrets

from diagnostic_msgs.msg import DiagnosticArray, KeyValue

AUTH_FIELD = "graph_auth"
AUTH_SIZE = 16  # bytes of the trailer: uint8[16] graph_auth, last in every msgs_defs type
KEY_ENV = "ACTIVETRACK_GRAPH_KEY"
KEY_BYTES = 32


class GraphKey:
    """A run's key: signs and verifies serialised messages (BLAKE2b, keyed, 128-bit tag)."""

    def __init__(self, key: bytes):
        if not isinstance(key, bytes) or not 16 <= len(key) <= 64:
            raise ValueError("a graph key must be 16..64 bytes")
        self._key = key

    @classmethod
    def generate(cls) -> GraphKey:
        return cls(secrets.token_bytes(KEY_BYTES))

    @classmethod
    def from_environment(cls, environ=None) -> GraphKey | None:
        """The key in ``ACTIVETRACK_GRAPH_KEY`` (hex), or None when it is unset or empty."""
        value = (os.environ if environ is None else environ).get(KEY_ENV, "")
        if not value:
            return None
        try:
            return cls(bytes.fromhex(value))
        except ValueError:
            raise ValueError(
                f"{KEY_ENV} must be {2 * KEY_BYTES} hex digits (16..64 bytes), got {len(value)} "
                "characters"
            ) from None

    def hex(self) -> str:
        return self._key.hex()

    def tag(self, data: bytes | memoryview) -> bytes:
        return hashlib.blake2b(data, key=self._key, digest_size=AUTH_SIZE).digest()

    def sign(self, serialized: bytes) -> bytes:
        """The message bytes with its trailer replaced by the tag of everything before it."""
        body = serialized[:-AUTH_SIZE]
        return body + self.tag(body)

    def verify(self, serialized: bytes) -> bool:
        """True if the message was signed with this key. Between processes DDS pads a payload
        to a multiple of 4 bytes, unmarked: the trailer may end up to 3 bytes before the end."""
        view = memoryview(serialized)
        for pad in range(4):
            end = len(view) - pad
            if end <= AUTH_SIZE + 4:  # 4: the CDR encapsulation header
                return False
            if hmac.compare_digest(
                self.tag(view[: end - AUTH_SIZE]), bytes(view[end - AUTH_SIZE : end])
            ):
                return True
        return False

    def _diagnostics_tag(self, array: DiagnosticArray) -> str:
        """Tag of a canonical text of the array (CDR is not canonical: its padding bytes are
        whatever the serialiser's buffer held), the ``graph_auth`` value left out."""
        h = array.header
        statuses = []
        for s in array.status:
            values = [[kv.key, kv.value] for kv in s.values if kv.key != AUTH_FIELD]
            statuses.append([bytes(s.level).hex(), s.name, s.message, s.hardware_id, values])
        text = json.dumps([h.stamp.sec, h.stamp.nanosec, h.frame_id, statuses])
        return self.tag(text.encode()).hex()

    def sign_diagnostics(self, array: DiagnosticArray) -> DiagnosticArray:
        """Append (or refresh) a ``graph_auth`` value on the array's first status."""
        if not array.status:
            return array
        values = [kv for kv in array.status[0].values if kv.key != AUTH_FIELD]
        values.append(KeyValue(key=AUTH_FIELD, value=self._diagnostics_tag(array)))
        array.status[0].values = values
        return array

    def verify_diagnostics(self, array: DiagnosticArray) -> bool:
        if not array.status or not array.status[0].values:
            return False
        last = array.status[0].values[-1]
        if last.key != AUTH_FIELD:
            return False
        return hmac.compare_digest(self._diagnostics_tag(array), last.value)


def is_signed_type(msg_type) -> bool:
    """True for message types that end with the ``graph_auth`` trailer (the msgs_defs types)."""
    fields = msg_type.get_fields_and_field_types()
    return list(fields)[-1:] == [AUTH_FIELD] and fields[AUTH_FIELD] == f"uint8[{AUTH_SIZE}]"
