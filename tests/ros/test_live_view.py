"""The live view (``activetrack run --foxglove``): a WebSocket client speaking the Foxglove
protocol subscribes during a short run and decodes what it receives against the run itself.

The client here is written from the protocol (``websockets`` as transport): JSON ``serverInfo``
and ``advertise``, a ``subscribe`` request, then binary message data (opcode 1: subscription id
u32, log time u64, payload) and server time (opcode 2: u64). Payloads are decoded with
``mcap_ros2`` from the schema the server advertised, not with the project's own types.
"""

from __future__ import annotations

import json
import socket
import struct
import threading
import time
from collections import defaultdict
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
from mcap_ros2.decoder import DecoderFactory
from parity import assert_same_run
from websockets.sync.client import connect

from activetrack_bringup import live_view
from activetrack_bringup.bag import graph_schemas
from activetrack_bringup.bag_io import open_bag
from activetrack_bringup.cli import build_parser
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros.trust import GraphKey

SCENARIO = "tests/ros/data/short_two_sensors.yaml"  # 8 epochs of 5 s, 2 platforms, no clamps
SUBPROTOCOL = "foxglove.sdk.v1"  # what foxglove-sdk 0.30 accepts
METRICS = "/" + topics.METRICS
MARKERS = "/" + topics.MARKERS
TRACKS = "/" + topics.TRACKS
WANTED = (METRICS, MARKERS, TRACKS, "/" + topics.CLOCK)
pytestmark = pytest.mark.ros


class FoxgloveClient(threading.Thread):
    """Connects, subscribes to ``wanted`` channels and collects their messages until stopped."""

    def __init__(self, url: str, wanted):
        super().__init__(daemon=True)
        self.url, self.wanted = url, set(wanted)
        self.server_info: dict = {}
        self.channels: dict[str, dict] = {}  # topic -> advertised channel
        self.messages = defaultdict(list)  # topic -> [(log time ns, payload)]
        self.times: list[int] = []  # server time broadcasts
        self.subscribed = threading.Event()
        self.stop = threading.Event()
        self.subprotocol = None
        self.failure: BaseException | None = None

    def run(self) -> None:
        try:
            with connect(self.url, subprotocols=[SUBPROTOCOL], open_timeout=5) as ws:
                self.subprotocol = ws.subprotocol
                while not self.wanted <= set(self.channels):
                    self._text(json.loads(ws.recv(timeout=5)))
                subs = {i: self.channels[t] for i, t in enumerate(sorted(self.wanted), start=1)}
                request = [{"id": i, "channelId": ch["id"]} for i, ch in subs.items()]
                ws.send(json.dumps({"op": "subscribe", "subscriptions": request}))
                self.subscribed.set()
                while not self.stop.is_set():
                    try:
                        data = ws.recv(timeout=0.05)
                    except TimeoutError:
                        continue
                    if isinstance(data, str):
                        self._text(json.loads(data))
                    elif data[0] == 1:  # message data
                        sub, log_time = struct.unpack_from("<IQ", data, 1)
                        self.messages[subs[sub]["topic"]].append((log_time, bytes(data[13:])))
                    elif data[0] == 2:  # server time
                        self.times.append(struct.unpack_from("<Q", data, 1)[0])
        except BaseException as exc:  # reported by the test
            self.failure = exc
            self.subscribed.set()

    def _text(self, msg: dict) -> None:
        if msg["op"] == "serverInfo":
            self.server_info = msg
        elif msg["op"] == "advertise":
            self.channels.update({ch["topic"]: ch for ch in msg["channels"]})

    def decoded(self, topic: str) -> list:
        """(log time, message) decoded with mcap_ros2 from the advertised schema."""
        ch = self.channels[topic]
        schema = SimpleNamespace(
            id=ch["id"], name=ch["schemaName"], encoding=ch["schemaEncoding"],
            data=ch["schema"].encode(),
        )  # fmt: skip
        decode = DecoderFactory().decoder_for(ch["encoding"], schema)
        return [(t, decode(payload)) for t, payload in self.messages[topic]]


@pytest.fixture(scope="module")
def viewed(tmp_path_factory):
    """A run with the live view and a subscribed client (subscribed before the run starts)."""
    with live_view.LiveServer(port=0) as server:
        client = FoxgloveClient(server.url, WANTED)
        client.start()
        assert client.subscribed.wait(10) and client.failure is None, client.failure
        deadline = time.monotonic() + 5
        while not all(server.subscriptions[t] for t in WANTED) and time.monotonic() < deadline:
            time.sleep(0.01)
        key = GraphKey.generate()
        nodes = []

        def attach(graph):
            live_view.attach(server, key)(graph)
            nodes.append(graph.nodes[-1])

        result = run_graph(
            SCENARIO, run_dir=tmp_path_factory.mktemp("viewed"), plots=False, graph_key=key,
            before_spin=attach,
        )  # fmt: skip
        steps = result.summary.steps
        deadline = time.monotonic() + 5
        while len(client.messages[METRICS]) < steps and time.monotonic() < deadline:
            time.sleep(0.01)
        time.sleep(0.2)  # the last markers and clock
        client.stop.set()
        client.join(5)
    assert client.failure is None, client.failure
    return SimpleNamespace(result=result, client=client, node=nodes[0])


def test_client_speaks_the_protocol_and_sees_every_graph_topic(viewed):
    c = viewed.client
    assert c.subprotocol == SUBPROTOCOL
    assert (
        c.server_info["name"] == live_view.SERVER_NAME and "time" in c.server_info["capabilities"]
    )
    schemas = graph_schemas()
    assert set(c.channels) == {"/" + t for t in topics.GRAPH_TOPICS}
    for topic, msgtype in topics.GRAPH_TOPICS.items():
        ch = c.channels["/" + topic]
        assert (ch["encoding"], ch["schemaEncoding"]) == ("cdr", "ros2msg")
        assert ch["schemaName"] == msgtype
        assert ch["schema"] == schemas[msgtype][0]  # the definition the bag embeds


def test_plot_channel_carries_the_summary_numbers(viewed):
    s = viewed.result.summary
    record = s.records[0]
    metrics = [m for _, m in viewed.client.decoded(METRICS)]
    assert [m.epoch for m in metrics] == list(range(1, s.steps + 1))
    assert all(list(m.target_ids) == ["t1"] for m in metrics)
    fields = ("error_x", "error_y", "bound_x", "bound_y")
    got = {f: [getattr(m, f)[0] for m in metrics] for f in fields}
    np.testing.assert_allclose(got["error_x"], s.rmse_x_t[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got["error_y"], s.rmse_y_t[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(got["bound_x"], s.bound_x_t[0], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(got["bound_y"], s.bound_y_t[0], rtol=1e-12, atol=1e-9)
    last = metrics[-1]
    assert last.steps == s.steps
    assert last.time_avg_rmse_x[0] == pytest.approx(s.time_avg_rmse_x[0], abs=1e-9)
    assert last.time_avg_rmse_y[0] == pytest.approx(s.time_avg_rmse_y[0], abs=1e-9)
    assert last.time_avg_bound_x[0] == pytest.approx(s.time_avg_bound_x[0], abs=1e-9)
    assert last.time_avg_bound_y[0] == pytest.approx(s.time_avg_bound_y[0], abs=1e-9)
    assert last.mean_gospa == pytest.approx(s.mean_gospa, abs=1e-9)
    np.testing.assert_allclose([m.gospa for m in metrics], s.gospa_t, rtol=0, atol=1e-9)
    for m in metrics:  # truth and estimate as the evaluator holds them
        truth = record.truth[m.epoch, 0]
        (track,) = record.tracks[m.epoch].tracks
        est = np.asarray(track.mean)
        (tp,), (ep,) = m.truth_positions, m.estimate_positions
        assert (tp.x, tp.y) == (truth[0], truth[2])
        assert ep.x == pytest.approx(est[0], abs=1e-9)
        assert m.position_error[0] == pytest.approx(np.hypot(*(est - truth)[[0, 2]]), abs=1e-9)
        assert sorted(m.measured_sensor_ids) == ["s1", "s2"]


def test_scene_channel_shows_truth_ellipse_and_planned_legs(viewed):
    record = viewed.result.summary.records[0]
    arrays = [m for _, m in viewed.client.decoded(MARKERS)]
    markers = [mk for a in arrays for mk in a.markers]
    truth = [mk for mk in markers if mk.ns == "truth"]
    K = viewed.result.summary.steps
    assert len(truth) == K
    end = tuple(record.truth[K, 0][[0, 2]])
    assert (truth[-1].pose.position.x, truth[-1].pose.position.y) == end
    assert any(mk.ns == "tracks" and len(mk.points) > 10 for mk in markers)  # 2-sigma ellipse
    legs = [mk for mk in markers if mk.ns == "next_leg"]
    assert len(legs) == 2 * K  # one per platform and decision
    epochs = [(mk.header.stamp.sec, mk.id) for mk in legs]
    for mk, (sec, j) in zip(legs, epochs, strict=True):
        k = round(sec / 5.0)
        start, end = (np.array([p.x, p.y]) for p in mk.points)
        np.testing.assert_allclose(start, record.platform_paths[k, j][[0, 2]], atol=1e-9)
        # No command is clamped here: the planned leg ends where the platform flies to.
        np.testing.assert_allclose(end, record.platform_paths[k + 1, j][[0, 2]], atol=1e-6)


def test_log_time_is_sim_time_and_bytes_are_the_bags(viewed):
    c, result = viewed.client, viewed.result
    end_ns = int(result.summary.steps * 5.0 * 1e9)
    assert c.times and c.times[-1] == end_ns  # the server's clock follows /clock
    stamps = [t for t, _ in c.messages[METRICS]]
    assert stamps == sorted(stamps) and stamps[-1] == end_ns
    with open_bag(result.bag) as bag:
        recorded = [data for _, _, data in bag.messages([TRACKS])]
    assert sorted(p for _, p in c.messages[TRACKS]) == sorted(bytes(d) for d in recorded)
    assert not [k for k in viewed.node.counters.counts if k.startswith("foreign.")]


def test_result_is_identical_with_the_view_on(viewed, tmp_path):
    plain = run_graph(SCENARIO, run_dir=tmp_path, record=False, plots=False)
    a, b = viewed.result.summary, plain.summary
    assert_same_run(a.records[0], b.records[0])
    for field in ("rmse_x_t", "rmse_y_t", "bound_x_t", "bound_y_t", "gospa_t"):
        assert getattr(a, field) == getattr(b, field), field


def _summary_numbers(path: Path) -> dict:
    d = json.loads(path.read_text())
    keys = (
        "time_avg_rmse_x", "time_avg_rmse_y", "time_avg_bound_x", "time_avg_bound_y",
        "rmse_x_t", "bound_y_t", "mean_gospa",
    )  # fmt: skip
    return {k: d[k] for k in keys} | {"complete": d["complete"]}


def test_command_line_with_foxglove_gives_the_same_summary(tmp_path, capsys):
    args = ["run", SCENARIO, "--no-plots", "--no-bag"]
    assert cli_main([*args, "--out", str(tmp_path / "a"), "--json", str(tmp_path / "a.json")]) == 0
    viewed = [*args, "--out", str(tmp_path / "b"), "--json", str(tmp_path / "b.json")]
    assert cli_main([*viewed, "--foxglove", "--port", "0"]) == 0
    assert "live view  ws://127.0.0.1:" in capsys.readouterr().out  # loopback by default
    assert _summary_numbers(tmp_path / "a.json") == _summary_numbers(tmp_path / "b.json")


class ClosingClient(threading.Thread):
    """Subscribes to the clock and reads until the server closes: how it closed."""

    def __init__(self, url: str):
        super().__init__(daemon=True)
        self.url = url
        self.statuses: list[dict] = []
        self.closed = None  # websockets' ConnectionClosed
        self.failure: BaseException | None = None

    def run(self) -> None:
        from websockets.exceptions import ConnectionClosed

        deadline = time.monotonic() + 30
        while True:  # the run starts its server after a second or two of imports
            try:
                ws = connect(self.url, subprotocols=[SUBPROTOCOL], open_timeout=5)
                break
            except OSError as exc:
                if time.monotonic() > deadline:
                    self.failure = exc
                    return
                time.sleep(0.1)
        try:
            with ws:
                while True:
                    data = ws.recv(timeout=60)
                    if not isinstance(data, str):
                        continue
                    msg = json.loads(data)
                    if msg["op"] == "advertise":  # channels come as their topics appear
                        clock = [c for c in msg["channels"] if c["topic"] == "/clock"]
                        if clock:  # (an advertise without it came first once: StopIteration)
                            request = [{"id": 1, "channelId": clock[0]["id"]}]
                            ws.send(json.dumps({"op": "subscribe", "subscriptions": request}))
                    elif msg["op"] == "status":
                        self.statuses.append(msg)
        except ConnectionClosed as closed:
            self.closed = closed
        except BaseException as exc:
            self.failure = exc


@pytest.mark.parametrize("interrupted", [False, True])
def test_the_live_view_closes_with_a_close_frame(tmp_path, capsys, monkeypatch, interrupted):
    """A client connected through a run sees it end with a status message and a WebSocket
    close frame, not a dropped connection: at the end of the run, and after Ctrl-C."""
    with socket.socket() as s:  # a free port for the run's server
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    client = ClosingClient(f"ws://127.0.0.1:{port}")
    client.start()
    if interrupted:  # Ctrl-C at the first epoch (the client subscribed before it)
        import activetrack_bringup.runner as runner_module

        real = runner_module._GraphRunner._check_started

        def interrupt(self):
            real(self)
            raise KeyboardInterrupt

        monkeypatch.setattr(runner_module._GraphRunner, "_check_started", interrupt)
    args = ["run", SCENARIO, "--foxglove", "--port", str(port), "--foxglove-wait", "30",
            "--no-plots", "--no-bag", "--out", str(tmp_path / "run")]  # fmt: skip
    assert cli_main(args) == (130 if interrupted else 0)
    client.join(30)
    assert client.failure is None, client.failure
    assert client.closed is not None and client.closed.rcvd is not None  # a close frame came
    # foxglove-sdk's close frame carries no code (1005 on this side); 1000/1001 would do too
    assert client.closed.rcvd.code in (1000, 1001, 1005)
    assert [s["message"] for s in client.statuses] == [live_view.STOPPED]


def test_a_port_in_use_fails_before_the_run(tmp_path, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        port = busy.getsockname()[1]
        out = tmp_path / "run"
        code = cli_main(["run", SCENARIO, "--foxglove", "--port", str(port), "--out", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("error: ") and f"127.0.0.1:{port}" in err[0]
    assert "in use" in err[0]
    assert not out.exists()  # nothing ran


def test_live_view_options_need_foxglove(tmp_path, capsys):
    code = cli_main(["run", SCENARIO, "--port", "9000", "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and "--foxglove" in err[0]
    assert not (tmp_path / "r").exists()


def _listening_addresses(port: int) -> set[str]:
    """Local addresses (hex, as /proc/net/tcp shows them) listening on ``port``."""
    found = set()
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        for line in Path(table).read_text().splitlines()[1:]:
            local, state = line.split()[1], line.split()[3]
            address, hex_port = local.split(":")
            if state == "0A" and int(hex_port, 16) == port:  # 0A: LISTEN
                found.add(address)
    return found


def test_server_binds_loopback_by_default():
    args = build_parser().parse_args(["run", SCENARIO, "--foxglove"])
    assert (args.host, args.port) == (None, None)  # the CLI then takes the defaults below
    assert (live_view.DEFAULT_HOST, live_view.DEFAULT_PORT) == ("127.0.0.1", 8765)
    with live_view.LiveServer(port=0) as server:
        assert server.url == f"ws://127.0.0.1:{server.port}"
        assert _listening_addresses(server.port) == {"0100007F"}  # 127.0.0.1 only


def _strings(node):
    """Every string in a JSON document, dictionary keys included."""
    if isinstance(node, dict):
        for k, v in node.items():
            yield k
            yield from _strings(v)
    elif isinstance(node, list):
        for v in node:
            yield from _strings(v)
    elif isinstance(node, str):
        yield node


def test_layout_shows_graph_topics_and_existing_fields_only():
    from activetrack_bringup.bag import message_class

    layout = json.loads(Path("docs/foxglove-layout.json").read_text())
    types = {"/" + t: message_class(m) for t, m in topics.GRAPH_TOPICS.items()}
    named = [s for s in _strings(layout) if s.startswith("/")]
    for path in named:
        topic, _, field = path.partition(".")
        assert topic in types, f"the layout names {topic}, not a graph topic"
        if field:  # a field, or an item of an array field (position_error[0])
            name = field.split(".")[0].split("[")[0]
            assert name in types[topic].get_fields_and_field_types(), path
    assert {METRICS, MARKERS, "/" + topics.SENSOR_SELECTION} <= {p.partition(".")[0] for p in named}
    panels = {}
    for s in _walk_panels(layout["content"]):
        panels.setdefault(s["panelType"], []).append(s["config"])
    assert panels["ThreeDee"][0]["fixedFrame"] == topics.FIXED_FRAME
    plotted = {p["value"] for c in panels["Plot"] for p in c["paths"]}
    assert {f"{METRICS}.position_error[0]", f"{METRICS}.position_bound[0]"} <= plotted


def _walk_panels(node):
    if node.get("type") == "panel":
        yield node
    for item in node.get("items", []) + node.get("tabs", []):
        yield from _walk_panels(item["content"])
