"""Live view in Foxglove (docs/live-view.md): a :class:`LiveServer` (foxglove-sdk WebSocket)
with one channel per graph topic, fed by a :class:`LiveViewNode` in the runner's graph with the
raw CDR bytes it receives, the graph's own only, under the names and schemas the run's bag has;
log time is the latest ``/clock``. The view only reads: it publishes nothing on the graph.
"""

from __future__ import annotations

import ipaddress
import threading
import time
from collections import Counter

from rclpy.expand_topic_name import expand_topic_name

from activetrack_bringup.bag import first_stamp_ns, graph_schemas, message_class
from activetrack_ros import graph as topics
from activetrack_ros.graph import GRAPH_TOPICS
from activetrack_ros.node_base import GraphNode, Rejected

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
SERVER_NAME = "activetrack"
NODE_NAME = "activetrack_live_view"
# Messages buffered per client: a lockstep run publishes in bursts far faster than real time.
BACKLOG = 16384
STOPPED = "activetrack: the run is over, the live view stops (its bag holds the whole run)"
# foxglove-sdk queues a status for its sender thread and has no flush: stopping at once can
# close a client's socket before the status reaches it, so stop() waits this long [s] first.
STATUS_GRACE_S = 0.25


class LiveViewError(ValueError):
    """The live view cannot be served as asked (a port in use, a host that cannot be bound)."""


def resolved_topic(topic: str, namespace: str = "") -> str:
    """The absolute name a graph topic has in ``namespace`` (what the nodes and the bag use)."""
    return expand_topic_name(topic, NODE_NAME, namespace or "/")


def is_loopback(host: str) -> bool:
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


class LiveServer:
    """The Foxglove WebSocket server with one channel per graph topic, started at once (so that
    a port in use fails before the run). ``port`` 0 takes a free port (see :attr:`port`)."""

    def __init__(
        self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, *, namespace: str = ""
    ) -> None:
        import foxglove
        from foxglove.websocket import Capability

        self.host = host
        self.subscriptions: Counter[str] = Counter()  # channel topic -> client subscriptions
        self._subscribed = threading.Event()
        self.context = foxglove.Context()
        try:
            self.server = foxglove.start_server(
                name=SERVER_NAME,
                host=host,
                port=port,
                capabilities=[Capability.Time],
                server_listener=self,
                context=self.context,
                message_backlog_size=BACKLOG,
            )
        except (RuntimeError, ValueError, OverflowError) as exc:
            reason = str(exc).removeprefix("FoxgloveError: ")
            raise LiveViewError(f"cannot serve the live view on {host}:{port}: {reason}") from None
        schemas = graph_schemas()
        self.channels = {}  # graph topic -> foxglove channel (its resolved name)
        for topic, msgtype in GRAPH_TOPICS.items():
            msgdef, _ = schemas[msgtype]
            self.channels[topic] = foxglove.Channel(
                resolved_topic(topic, namespace),
                schema=foxglove.Schema(name=msgtype, encoding="ros2msg", data=msgdef.encode()),
                message_encoding="cdr",
                context=self.context,
            )

    @property
    def port(self) -> int:
        return self.server.port

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    def wait_for_subscriber(self, timeout: float) -> bool:
        """Block until a client subscribed to a channel, or ``timeout`` seconds pass."""
        deadline = time.monotonic() + timeout
        while not self._subscribed.is_set():  # in slices: Ctrl-C stays responsive
            left = deadline - time.monotonic()
            if left <= 0:
                return False
            self._subscribed.wait(min(left, 0.1))
        return True

    def on_subscribe(self, client, channel) -> None:
        """The server's callback (on the SDK's thread): a client watches ``channel``."""
        self.subscriptions[channel.topic] += 1
        self._subscribed.set()

    def on_unsubscribe(self, client, channel) -> None:
        self.subscriptions[channel.topic] -= 1

    def log(self, topic: str, data: bytes, log_time_ns: int) -> None:
        self.channels[topic].log(data, log_time=log_time_ns)

    def broadcast_time(self, time_ns: int) -> None:
        self.server.broadcast_time(time_ns)

    def stop(self) -> None:
        """Tell the clients the run is over (a Foxglove status message), unadvertise the
        channels and stop: the server sends each client a WebSocket close frame (foxglove-sdk
        sends it without a status code, which RFC 6455 allows: clients report 1005)."""
        from foxglove.websocket import StatusLevel

        self.server.publish_status(STOPPED, StatusLevel.Info, id="activetrack-stopped")
        for channel in self.channels.values():
            channel.close()
        time.sleep(STATUS_GRACE_S)
        self.server.stop()

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc) -> None:
        self.stop()


class LiveViewNode(GraphNode):
    """Forwards the graph's topics to a :class:`LiveServer`: raw bytes, the graph's own only.

    ``forwarded`` counts the messages sent on per graph topic; foreign ones end in the node's
    ``foreign.<Type>`` counters, as in every graph node."""

    def __init__(self, server: LiveServer, **kwargs):
        super().__init__(NODE_NAME, **kwargs)
        self.server = server
        self.clock_ns = 0  # sim time of the latest /clock: the log time of what follows
        self.forwarded: Counter[str] = Counter()
        for topic, msgtype in GRAPH_TOPICS.items():
            self.subscribe_raw(message_class(msgtype), topic, self._forwarder(topic))

    def _forwarder(self, topic: str):
        def forward(data: bytes) -> None:
            if topic == topics.CLOCK:
                try:
                    self.clock_ns = first_stamp_ns(data)
                except ValueError as exc:  # any writer may publish a clock
                    raise Rejected("undecodable", f"clock: {exc}") from None
                self.server.broadcast_time(self.clock_ns)
            self.server.log(topic, data, self.clock_ns)
            self.forwarded[topic] += 1

        return forward


def attach(server: LiveServer, graph_key, namespace: str = ""):
    """A runner ``before_spin`` hook that adds the live view's node to the run's graph."""

    def before_spin(graph) -> None:
        ns = namespace or None  # none: the node's default
        graph.add(LiveViewNode(server, graph_key=graph_key, context=graph.context, namespace=ns))

    return before_spin
