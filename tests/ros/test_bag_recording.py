"""The recorder's bags: what independent readers see, a recorder killed with SIGKILL (read
directly and after `bag recover`), argument errors of play/record, and `bag retrack` failing
fast (one line, exit code 2, no hang) when the scenario does not match the bag."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections import Counter, defaultdict
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest
import yaml
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from mcap_ros2.decoder import DecoderFactory
from rclpy.node import Node
from rclpy.serialization import deserialize_message, serialize_message
from recorded import read_topic
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore
from rosgraph_msgs.msg import Clock

from activetrack.scenarios import load_scenario
from activetrack_bringup import bag as bagmod
from activetrack_bringup import interrupts, mcap_writer
from activetrack_bringup import retrack as retrack_mod
from activetrack_bringup.bag import BagPlayer, BagRecorder, bag_info, graph_schemas
from activetrack_bringup.bag_io import BagError, Rosbag2Writer, TopicSpec, open_bag
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_bringup.mcap_writer import CHUNK_SIZE
from activetrack_bringup.retrack import RetrackError, retrack
from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros.convert import header
from activetrack_ros.graph import GRAPH_TOPICS, graph_topic_of
from activetrack_ros.trust import GraphKey
from msgs_defs.msg import PlatformState, Scan, TrackArray

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def run_bag(tmp_path_factory):
    """One recorded closed-loop run, shared by the tests of this module (read-only)."""
    return run_graph(SCENARIO, run_dir=tmp_path_factory.mktemp("rec"), plots=False).bag


def cli(capsys, *argv):
    """Run the command line; (rc, stdout, stderr). Never a traceback, errors in one line."""
    try:
        rc = cli_main([str(a) for a in argv])
    except SystemExit as exc:  # argparse's own checks
        rc = exc.code
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    assert rc in (0, 2), (rc, out, err)
    if rc == 2 and "usage:" not in err:
        errors = [line for line in err.splitlines() if line.startswith("error: ")]
        assert len(errors) == 1, err
    return rc, out, err


# --- what the recorder writes -----------------------------------------------------------


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def test_independent_mcap_reader_decodes_the_bag(run_bag):
    """mcap + mcap_ros2 (not rosbags, not this package) read and decode every message, with
    chunk and data-section CRCs checked; schemas, hashes and QoS are as rosbag2 writes them."""
    mcap_file = run_bag / "bag.mcap"
    schemas = graph_schemas()
    rclpy_tracks = {m.epoch: m for m in read_topic(run_bag, topics.TRACKS, TrackArray)}
    counts = Counter()
    log_times, stamps = defaultdict(list), []
    with open(mcap_file, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        for channel in summary.channels.values():
            schema = summary.schemas[channel.schema_id]
            assert channel.message_encoding == "cdr" and schema.encoding == "ros2msg"
            assert channel.topic.startswith("/")  # resolved names, as rosbag2 stores them
            topic = graph_topic_of(channel.topic)
            msgdef, rihs01 = schemas[GRAPH_TOPICS[topic]]
            assert schema.name == GRAPH_TOPICS[topic]
            assert schema.data.decode() == msgdef
            assert channel.metadata["topic_type_hash"] == rihs01
            qos = yaml.safe_load(channel.metadata["offered_qos_profiles"])
            latched = topic in topics.LATCHED_TOPICS or topic == topics.TF_STATIC
            assert qos[0]["durability"] == ("transient_local" if latched else "volatile")
            assert qos[0]["reliability"] == "reliable"
            if topic in topics.LATCHED_TOPICS:  # the whole run for late joiners
                assert qos[0]["history"] == "keep_last"
                assert qos[0]["depth"] == topics.history_depth(load_scenario(SCENARIO))
        for _, channel, message, decoded in reader.iter_decoded_messages():
            counts[channel.topic] += 1
            log_times[graph_topic_of(channel.topic)].append(message.log_time)
            if hasattr(decoded, "header"):
                stamps.append((message.log_time, _ns(decoded.header.stamp)))
            if graph_topic_of(channel.topic) == topics.TRACKS:
                ref = rclpy_tracks[decoded.epoch]
                (item,), (ref_item,) = decoded.tracks, ref.tracks
                np.testing.assert_array_equal(item.state, ref_item.state)
                np.testing.assert_array_equal(item.covariance, ref_item.covariance)
                np.testing.assert_array_equal(item.samples, ref_item.samples)
                assert decoded.filter_kind == ref.filter_kind
        chunks = summary.chunk_indexes
    info = bag_info(run_bag)
    assert info["intact"] and not info["damage"]
    assert dict(counts) == {t: v["count"] for t, v in info["topics"].items() if v["count"]}
    # Log time is sim time (the graph's clock): the timeline spans the scenario, each
    # message is logged within an epoch of its stamp, and the clock's own log times are its
    # values.
    sc = load_scenario(SCENARIO)
    dt_ns = round(sc.dt * 1e9)
    assert info["duration_s"] == pytest.approx(sc.steps * sc.dt, abs=sc.dt)
    assert max(log_times[topics.CLOCK]) == sc.steps * dt_ns
    assert len(stamps) > 100
    assert all(abs(log - stamp) <= dt_ns for log, stamp in stamps)
    # Every chunk has its CRC; the first one holds the definitions only; chunks stay small.
    biggest = len(rclpy_tracks[0].tracks[0].samples) * 8 + 2000  # the largest message
    with open(mcap_file, "rb") as f:
        records = list(StreamReader(f, validate_crcs=True, emit_chunks=True).records)
    chunk_records = [r for r in records if type(r).__name__ == "Chunk"]
    assert len(chunk_records) == len(chunks) >= 2
    assert all(c.uncompressed_crc for c in chunk_records)
    assert chunks[0].message_index_offsets == {}
    assert all(c.uncompressed_size < CHUNK_SIZE + biggest for c in chunk_records)
    data_end = next(r for r in records if type(r).__name__ == "DataEnd")
    assert data_end.data_section_crc != 0


def test_metadata_yaml_is_rosbag2_version_9(run_bag):
    meta = yaml.safe_load((run_bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap"
    assert meta["ros_distro"] == "jazzy"
    assert meta["relative_file_paths"] == ["bag.mcap"]
    assert meta["custom_data"] == {"activetrack_state": "closed"}
    schemas = graph_schemas()
    listed = {t["topic_metadata"]["name"]: t for t in meta["topics_with_message_count"]}
    assert set(listed) == {"/" + t for t in GRAPH_TOPICS}
    info = bag_info(run_bag)
    for name, entry in listed.items():
        assert entry["message_count"] == info["topics"][name]["count"]
        tm = entry["topic_metadata"]
        assert tm["type_description_hash"] == schemas[tm["type"]][1]
        assert tm["serialization_format"] == "cdr"
    assert meta["message_count"] == info["messages"]
    with Reader(run_bag) as reader:  # rosbags: metadata and storage agree
        assert reader.message_count == info["messages"]
        assert {c.topic: c.msgcount for c in reader.connections} == {
            t: v["count"] for t, v in info["topics"].items()
        }


def test_a_lockstep_bag_starts_at_sim_time_0(run_bag):
    """A start of 0 is a start: metadata.yaml, the MCAP statistics, rosbags and bag info all
    give start 0 and duration steps x dt (rosbags' end is exclusive: one nanosecond more)."""
    scenario = load_scenario(SCENARIO)
    duration_ns = round(scenario.steps * scenario.dt * 1e9)
    assert duration_ns == 40_000_000_000
    meta = yaml.safe_load((run_bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["starting_time"]["nanoseconds_since_epoch"] == 0
    assert meta["duration"]["nanoseconds"] == duration_ns
    assert meta["files"][0]["starting_time"]["nanoseconds_since_epoch"] == 0
    assert meta["files"][0]["duration"]["nanoseconds"] == duration_ns
    with open(run_bag / "bag.mcap", "rb") as f:
        stats = make_reader(f).get_summary().statistics
    assert (stats.message_start_time, stats.message_end_time) == (0, duration_ns)
    with Reader(run_bag) as reader:
        assert (reader.start_time, reader.duration) == (0, duration_ns + 1)
        assert min(t for _, t, _ in reader.messages()) == 0
    assert bag_info(run_bag)["duration_s"] == duration_ns * 1e-9


def test_a_bag_whose_metadata_misstates_its_span_is_named_and_recovered(run_bag, tmp_path):
    """A bag written before that fix (metadata.yaml: start 10 s, duration 30 s for messages at
    0-40 s): bag info names the disagreement, bag recover rewrites metadata.yaml."""
    from activetrack_bringup.bag_recover import recover

    bag = tmp_path / "old"
    shutil.copytree(run_bag, bag)
    meta_path = bag / "metadata.yaml"
    meta = yaml.safe_load(meta_path.read_text())
    info = meta["rosbag2_bagfile_information"]
    info["starting_time"]["nanoseconds_since_epoch"] = 10_000_000_000
    info["duration"]["nanoseconds"] = 30_000_000_000
    meta_path.write_text(yaml.safe_dump(meta, sort_keys=False))
    found = bag_info(bag)
    assert not found["intact"] and [d["kind"] for d in found["damage"]] == ["metadata"]
    assert found["damage"][0]["what"] == (
        f"{meta_path} gives start 10 s and duration 30 s; the messages start at 0 s and span 40 s"
    )
    assert recover(bag).changed
    fixed = yaml.safe_load(meta_path.read_text())["rosbag2_bagfile_information"]
    assert fixed["starting_time"]["nanoseconds_since_epoch"] == 0
    assert fixed["duration"]["nanoseconds"] == 40_000_000_000
    assert bag_info(bag)["intact"]


# --- a recorder killed with SIGKILL -----------------------------------------------------

CHILD = """
import sys, time
from rclpy.node import Node
from activetrack_bringup.bag import BagRecorder
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_ros import graph as topics
from msgs_defs.msg import Scan
from rosgraph_msgs.msg import Clock
from builtin_interfaces.msg import Time

kept = (topics.SCANS, topics.CLOCK)
quiet = {"start_parameter_services": False}
with InProcessGraph() as g:
    rec = g.add(BagRecorder(sys.argv[1], {t: topics.GRAPH_TOPICS[t] for t in kept},
                            context=g.context, **quiet))
    node = g.add(Node("kill_test_publisher", context=g.context, **quiet))
    pub = node.create_publisher(Scan, topics.SCANS, topics.writer_qos(topics.SCANS))
    clock = node.create_publisher(Clock, topics.CLOCK, topics.writer_qos(topics.CLOCK))
    k = 0
    while True:
        k += 1
        now = time.time_ns()  # the clock is wall time here: log times measure the loss
        clock.publish(Clock(clock=Time(sec=now // 10**9, nanosec=now % 10**9)))
        pub.publish(Scan(epoch=k, sensor_id="s1", dim=1, detections=[1e-3 * k]))
        g.spin_until(lambda: rec.count >= 2 * k, timeout=1.0, step=0.001)
        time.sleep(0.003)
"""


def _metadata_count(bag: Path) -> int:
    try:
        meta = yaml.safe_load((bag / "metadata.yaml").read_text())
        return meta["rosbag2_bagfile_information"]["message_count"]
    except (OSError, TypeError, KeyError, yaml.YAMLError):
        return -1


def test_kill_9_mid_recording_loses_at_most_the_last_chunk(tmp_path, capsys):
    bag = tmp_path / "killed"
    env = dict(os.environ)
    env.pop("_ROS_WHEELS_BOOTSTRAP_COMPLETE", None)
    env["ROS_DOMAIN_ID"] = str(150 + os.getpid() % 50)  # private; in-process traffic only
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "OFF"
    child = subprocess.Popen([sys.executable, "-c", CHILD, str(bag)], env=env)
    try:
        deadline = time.monotonic() + 60
        while _metadata_count(bag) < 150:  # some chunks and a metadata rewrite on disk
            assert child.poll() is None, "the recording child died"
            assert time.monotonic() < deadline, "the child recorded nothing"
            time.sleep(0.05)
        time.sleep(0.3)  # mid-chunk
        child.send_signal(signal.SIGKILL)
        killed_ns = time.time_ns()
    finally:
        child.kill()
        child.wait()
    listed = _metadata_count(bag)  # metadata.yaml of the killed run: current within ~1 s

    rc, out, err = cli(capsys, "bag", "info", bag, "--json", tmp_path / "info.json")
    assert rc == 2 and "no summary: the writer did not finish" in err  # read directly
    assert f"bag {bag}:" in out and topics.SCANS in out
    info = json.loads((tmp_path / "info.json").read_text())
    n = info["topics"]["/" + topics.SCANS]["count"]
    assert n >= 100 and info["messages"] >= listed > 0
    with open_bag(bag) as b:
        assert not b.lost  # incomplete, nothing lost before the cut
        epochs = [
            deserialize_message(d, Scan).epoch for _, _, d in b.messages(["/" + topics.SCANS])
        ]
        end_ns = b.end_time
    assert epochs == list(range(1, n + 1))  # a gapless prefix of what was published
    # mcap's own stream reader (CRCs on) reads the same messages before it stops at the cut.
    seen = 0
    with open(bag / "killed.mcap", "rb") as f:
        try:
            for record in StreamReader(f, validate_crcs=True).records:
                seen += type(record).__name__ == "Message"
        except Exception:  # its error at the cut, whatever it is
            pass
    assert seen == info["messages"]
    lost_s = (killed_ns - end_ns) * 1e-9
    assert lost_s < 1.5, f"the last {lost_s:.2f} s were lost"  # chunks close within 0.5 s

    rc, out, err = cli(capsys, "bag", "recover", bag)
    assert rc == 0 and f"kept {info['messages']} messages" in out
    assert (bag / "killed.mcap.damaged").exists() and (bag / "metadata.yaml.old").exists()
    rc, out, err = cli(capsys, "bag", "info", bag)
    assert rc == 0 and not err
    with AnyReader([bag], default_typestore=get_typestore(Stores.EMPTY)) as reader:
        got = [
            reader.deserialize(d, c.msgtype).epoch
            for c, _, d in reader.messages()
            if c.topic == "/" + topics.SCANS
        ]
    assert got == epochs
    # rosbags reads the killed run's own metadata.yaml (next to the recovered file).
    twin = tmp_path / "twin"
    twin.mkdir()
    shutil.copy(bag / "metadata.yaml.old", twin / "metadata.yaml")
    shutil.copy(bag / "killed.mcap", twin / "killed.mcap")
    with Reader(twin) as reader:
        assert reader.message_count == listed
        assert {c.topic for c in reader.connections} == {"/" + topics.SCANS, "/" + topics.CLOCK}


def test_recorder_metadata_tracks_the_disk_while_recording(tmp_path):
    """metadata.yaml says 'recording', counts only flushed messages, and the bag reads as
    incomplete (not damaged) before close; intact after."""
    bag = tmp_path / "live"
    with InProcessGraph() as g:
        clock_only = {topics.CLOCK: GRAPH_TOPICS[topics.CLOCK]}
        rec = g.add(bagmod.BagRecorder(bag, clock_only, context=g.context))
        node = g.add(Node("pub", context=g.context))
        pub = node.create_publisher(Clock, topics.CLOCK, topics.writer_qos(topics.CLOCK))
        meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
        assert meta["message_count"] == 0
        assert meta["custom_data"]["activetrack_state"] == "recording"
        for _ in range(20):
            pub.publish(Clock())
        g.spin_until(lambda: rec.count == 20, timeout=5)
        g.spin_until(lambda: _metadata_count(bag) == 20, timeout=3)  # timer: chunk + metadata
        assert _metadata_count(bag) == 20
        with open_bag(bag) as b:
            assert b.message_count == 20 and not b.lost and not b.intact
        rec.close()
    assert bag_info(bag)["intact"]


# --- argument errors --------------------------------------------------------------------


@pytest.mark.parametrize("rate", [0, -1.0, float("nan"), float("inf"), "fast"])
def test_player_rejects_bad_rates(run_bag, rate):
    with pytest.raises(ValueError, match="rate must be a positive"):
        BagPlayer(run_bag, rate=rate)


def test_play_and_record_errors_are_one_line(run_bag, tmp_path, capsys):
    for rate in ("0", "-2", "nan", "inf"):
        rc, _, err = cli(capsys, "play", run_bag, "--rate", rate)
        assert rc == 2 and "rate" in err
    rc, _, err = cli(capsys, "play", run_bag, "--topics", "/nope", "--rate", "100")
    assert rc == 2 and "topics not in the bag: ['/nope']" in err
    rc, out, err = cli(capsys, "play", run_bag, "--topics", topics.PLAN_REPORT, "--rate", "100")
    assert rc == 0 and "published 8 messages" in out and not err
    rc, _, err = cli(capsys, "record", run_bag)  # an existing path
    assert rc == 2 and "exists already" in err
    rc, _, err = cli(capsys, "play", tmp_path / "missing")
    assert rc == 2 and "no such bag" in err


# --- retrack: fails fast on a scenario that does not match ------------------------------


def _variant(tmp_path, name, edit):
    doc = yaml.safe_load(Path(SCENARIO).read_text())
    doc["name"] = "variant"
    edit(doc)
    path = tmp_path / f"{name}.yaml"
    path.write_text(yaml.safe_dump(doc))
    return path


def _sensor_ids(doc):
    doc["platforms"][0]["sensors"][0]["id"] = "x1"


def _platform_ids(doc):
    doc["platforms"][1]["id"] = "q2"


def _dt(doc):
    doc["dt"] = 4.0


def _fewer_steps(doc):
    doc["steps"] = 5


def _more_steps(doc):
    doc["steps"] = 12


def _state(doc):
    doc["target"]["motion"] = {"model": "circular", "sigma_omega": 1e-4, "sigma_v": 1e-3}
    doc["target"]["prior"] = {"mean": [0.0, 1000.0, 1000.0, 0.0, 50.0], "var": [0.01] * 5}
    doc["planner"] = {"enabled": False}


def _target(doc):
    doc["target"]["id"] = "t9"


def _sensor_kind(doc):
    s = doc["platforms"][0]["sensors"][0]
    doc["platforms"][0]["sensors"][0] = {
        "id": s["id"],
        "kind": "range_bearing",
        "sigma_r": 1.0,
        "sigma_b": 0.01,
    }


@pytest.mark.parametrize(
    "edit, expect",
    [
        (_sensor_ids, "sensors ['s1'] that scenario"),
        (_platform_ids, "sensor 's2' is on platform 'p2' in the bag, on 'q2' in scenario"),
        (_dt, "scenario variant has dt = 4 s"),
        (_fewer_steps, "the recorded run has 8 steps (its simulator's diagnostics), scenario"),
        (_more_steps, "the recorded run has 8 steps (its simulator's diagnostics), scenario"),
        (_state, "the recorded tracks' state is ncv (x, xdot, y, ydot)"),
        (_target, "the recorded tracks are of targets ['t1']"),
        (_sensor_kind, "is a bearing sensor in the bag but a range_bearing sensor in scenario"),
    ],
    ids=["sensor", "platform", "dt", "fewer-steps", "more-steps", "state", "target", "kind"],
)
def test_retrack_fails_fast_when_the_scenario_does_not_match(
    run_bag, tmp_path, capsys, edit, expect
):
    scenario = _variant(tmp_path, "variant", edit)
    start = time.monotonic()
    rc, _, err = cli(capsys, "bag", "retrack", run_bag, "--scenario", scenario)
    assert rc == 2 and expect in err, err
    assert "wrong --scenario?" in err and "(the run used scenario 'short_two_sensors')" in err
    assert time.monotonic() - start < 5.0


def _bag_of(tmp_path, name, messages: dict[str, list]) -> Path:
    """A bag written with the project's writer from (topic -> [serialized message])."""
    schemas = graph_schemas()
    specs = [TopicSpec(t, GRAPH_TOPICS[t], *schemas[GRAPH_TOPICS[t]]) for t in messages]
    writer = Rosbag2Writer(tmp_path / name, specs, state="closed")
    t = 1
    for topic, items in messages.items():
        for data in items:
            writer.write(writer.channel_ids[topic], t, data)
            t += 1
    writer.close()
    return tmp_path / name


def test_retrack_says_when_there_is_nothing_to_retrack(run_bag, tmp_path, capsys):
    with open_bag(run_bag) as b:
        clock = [d for _, _, d in b.messages(["/" + topics.CLOCK])]
        tracks = [d for _, _, d in b.messages(["/" + topics.TRACKS])]
    no_scans = _bag_of(tmp_path, "no_scans", {topics.CLOCK: clock, topics.TRACKS: tracks})
    rc, _, err = cli(capsys, "bag", "retrack", no_scans, "--scenario", SCENARIO)
    assert rc == 2 and "holds no scans" in err
    rc, _, err = cli(capsys, "bag", "retrack", tmp_path / "nope", "--scenario", SCENARIO)
    assert rc == 2 and "no such bag" in err
    rc, _, err = cli(capsys, "bag", "retrack", run_bag, "--scenario", tmp_path / "none.yaml")
    assert rc == 2
    # A filter nobody registered (the scenario's plugins would register theirs first).
    rc, _, err = cli(capsys, "bag", "retrack", run_bag, "--scenario", SCENARIO, "--filter", "ukf")
    assert rc == 2 and "--filter: " in err and "'ekf' or 'pf'" in err and "'ukf'" in err


def test_retrack_wait_is_bounded_when_the_tracker_stops(run_bag, monkeypatch):
    class StuckTracker(retrack_mod.TrackerNode):
        def publish_tracks(self, tracks):  # publishes the priors, then falls silent
            if tracks.epoch == 0:
                super().publish_tracks(tracks)

    monkeypatch.setattr(retrack_mod, "TrackerNode", StuckTracker)
    start = time.monotonic()
    with pytest.raises(RetrackError, match="stopped at epoch 0: no tracks for epoch 1 within"):
        retrack(run_bag, SCENARIO, stall_timeout=0.5)
    assert time.monotonic() - start < 5.0


def test_retrack_refuses_a_bag_with_lost_data(run_bag, tmp_path):
    bag = tmp_path / "damaged"
    shutil.copytree(run_bag, bag)
    data = bytearray((bag / "bag.mcap").read_bytes())
    with open(bag / "bag.mcap", "rb") as f:  # a byte inside a message chunk, whatever the layout
        chunk = make_reader(f).get_summary().chunk_indexes[1]
    data[chunk.chunk_start_offset + chunk.chunk_length // 2] ^= 0xFF
    (bag / "bag.mcap").write_bytes(data)
    with pytest.raises(BagError, match=r"bag.mcap: corrupt chunk at offset \d+ \(CRC mismatch"):
        retrack(bag, SCENARIO)


def test_a_full_disk_stops_the_recording_not_the_graph(tmp_path, monkeypatch, capsys):
    bag = tmp_path / "full"
    with InProcessGraph() as g:
        clock_only = {topics.CLOCK: GRAPH_TOPICS[topics.CLOCK]}
        rec = g.add(bagmod.BagRecorder(bag, clock_only, context=g.context))
        node = g.add(Node("pub", context=g.context))
        pub = node.create_publisher(Clock, topics.CLOCK, topics.writer_qos(topics.CLOCK))
        for _ in range(5):
            pub.publish(Clock())
        assert g.spin_until(lambda: _metadata_count(bag) == 5, timeout=5)  # on disk

        def full(fd, parts):
            raise OSError(28, "No space left on device")

        monkeypatch.setattr(mcap_writer.os, "writev", full)
        for _ in range(5):
            pub.publish(Clock())
        assert g.spin_until(lambda: rec.failed is not None, timeout=5)  # the chunk's age
        assert "No space left on device" in rec.failed
        monkeypatch.undo()
        pub.publish(Clock())
        g.spin_until(lambda: False, timeout=0.1)  # the graph goes on; nothing more recorded
    assert rec.count == 10
    rc, out, _ = cli(capsys, "bag", "recover", bag)
    assert rc == 0 and "kept 5 messages" in out


def test_play_follows_the_recorded_sim_time(run_bag, monkeypatch):
    """`play --rate R`: a message logged at sim time t goes out R times faster than t, i.e. at
    wall time t / R after the first; the whole run takes its simulated duration / R."""
    now = [1000.0]
    monkeypatch.setattr(bagmod, "time", SimpleNamespace(monotonic=lambda: now[0]))
    with open_bag(run_bag) as b:
        log_times = sorted(t for _, t, _ in b.messages(list(b.usable_topics)))
    sc = load_scenario(SCENARIO)
    rate = 4.0
    with InProcessGraph() as g:
        player = g.add(BagPlayer(run_bag, rate=rate, context=g.context))
        t0 = log_times[0]
        player.play_step(max_burst=10**6)  # the first message starts the clock
        assert player.published == log_times.count(t0) > 0
        for k in range(1, sc.steps + 1):
            due = (k * sc.dt * 1e9 - t0) * 1e-9 / rate
            now[0] = 1000.0 + due - 1e-6
            player.play_step(max_burst=10**6)
            assert player.published == sum(t < k * sc.dt * 1e9 for t in log_times), k
            now[0] = 1000.0 + due
            player.play_step(max_burst=10**6)
            assert player.published == sum(t <= k * sc.dt * 1e9 for t in log_times), k
        player.play_step()
        assert player.done and player.published == len(log_times)


def test_a_foreign_clock_cannot_stretch_or_reorder_a_keyed_recording(tmp_path):
    """`/clock` cannot be signed (a standard type): with the graph's key the recorder takes a
    clock value as log time only within clock_lead after the newest stamp of the graph's own
    messages, and never backwards; the others are recorded but counted, not used."""
    key = GraphKey(bytes(range(32)))

    def clock(seconds: float) -> bytes:
        return serialize_message(Clock(clock=header(seconds).stamp))

    def state(seconds: float, epoch: int) -> bytes:
        return key.sign(serialize_message(PlatformState(header=header(seconds), epoch=epoch)))

    kept = {t: GRAPH_TOPICS[t] for t in (topics.CLOCK, topics.PLATFORM_STATES)}
    with InProcessGraph() as g:
        rec = g.add(
            BagRecorder(tmp_path / "b", kept, graph_key=key, clock_lead=10.0, context=g.context)
        )
        on_state = rec._verifier(key, topics.PLATFORM_STATES, PlatformState)
        rec._on_clock(clock(0.0))
        on_state(state(0.0, 0))
        rec._on_clock(clock(5.0))  # the graph's next epoch: within the lead
        rec._on_clock(clock(1e6))  # a foreign writer's far future: refused
        on_state(state(5.0, 1))
        rec._on_clock(clock(2.0))  # backwards: refused
        on_state(state(5.0, 1))
        rec.close()
    assert rec.clock_refused == 2
    with open_bag(tmp_path / "b") as b:
        logged = [(graph_topic_of(n), t) for n, t, _ in b.messages(list(b.topics))]
    assert [t for n, t in logged if n == topics.PLATFORM_STATES] == [0, 5 * 10**9, 5 * 10**9]
    assert max(t for _, t in logged) == 5 * 10**9


def test_a_signal_during_a_write_is_raised_after_it(tmp_path, monkeypatch):
    """SIGTERM (or Ctrl-C) arriving while the recorder writes is raised once the write is done:
    raised inside a chunk's write(2) it would leave half a chunk on disk."""
    kept = {topics.CLOCK: GRAPH_TOPICS[topics.CLOCK]}
    data = serialize_message(Clock(clock=header(1.0).stamp))
    with InProcessGraph() as g:
        rec = g.add(BagRecorder(tmp_path / "b", kept, context=g.context))
        real = rec.writer.write

        def interrupted_write(*args):
            os.kill(os.getpid(), signal.SIGTERM)  # the handler runs at the next bytecode
            real(*args)
            rec.writer._mcap.flush()  # the chunk reaches the file inside the same write

        monkeypatch.setattr(rec.writer, "write", interrupted_write)
        with pytest.raises(interrupts.Terminated), interrupts.raising():
            rec._write(topics.CLOCK, data)
        assert rec.count == 1  # the write finished before the signal was raised
        rec.close()
    info = bag_info(tmp_path / "b")
    assert info["intact"] and info["topics"]["/clock"]["count"] == 1


def test_a_bag_of_two_namespaces_needs_the_namespace_named(run_bag, tmp_path, capsys):
    """Graph topics are found under any namespace; where two namespaces hold one, the name
    must say which (retrack, read_topic and play alike)."""
    with open_bag(run_bag) as b:
        tracks = [d for _, _, d in b.messages(["/" + topics.TRACKS])]
    schemas = graph_schemas()
    msgtype = GRAPH_TOPICS[topics.TRACKS]
    names = [f"/g{i}/{topics.TRACKS}" for i in (1, 2)]
    specs = [TopicSpec(n, msgtype, *schemas[msgtype]) for n in names]
    writer = Rosbag2Writer(tmp_path / "two", specs, state="closed")
    for t, data in enumerate(tracks):
        for n in names:
            writer.write(writer.channel_ids[n], t, data)
    writer.close()
    with pytest.raises(BagError, match="several namespaces hold activetrack/tracks"):
        read_topic(tmp_path / "two", topics.TRACKS, TrackArray)
    got = read_topic(tmp_path / "two", names[1], TrackArray)
    assert [m.epoch for m in got] == list(range(len(tracks)))
    rc, _, err = cli(capsys, "play", tmp_path / "two", "--topics", topics.TRACKS, "--rate", "100")
    assert rc == 2 and "name the topic with its namespace" in err
