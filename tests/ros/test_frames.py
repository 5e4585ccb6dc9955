"""Frames that RViz and Foxglove show without configuration (docs/frames.md): /tf holds each
platform, the target's truth and the track's estimate in the fixed frame, /tf_static each
sensor on its platform; every header names the fixed frame."""

import math
from dataclasses import replace

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from recorded import read_topic
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from activetrack.scenarios import load_scenario
from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros.convert import header
from activetrack_ros.graph import qos_for
from msgs_defs.msg import GroundTruthArray, PlatformState, Scan, TrackArray
from tracker_node.tracker_node import TrackerNode

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    return run_graph(SCENARIO, run_dir=tmp_path_factory.mktemp("frames"), plots=False).bag


def _ns(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _yaw(q) -> float:
    return 2 * math.atan2(q.z, q.w)


def test_tf_places_platforms_truth_and_estimate(bag):
    sc = load_scenario(SCENARIO)
    transforms = {}  # (child, stamp) -> transform
    for msg in read_topic(bag, topics.TF, TFMessage):
        for t in msg.transforms:
            assert t.header.frame_id == "world"
            transforms[(t.child_frame_id, _ns(t.header.stamp))] = t
    children = {c for c, _ in transforms}
    platforms = {f"platform/{p.id}" for p in sc.platforms}
    target = sc.target.id
    assert children == platforms | {f"target/{target}/truth", f"target/{target}/estimate"}
    assert len(transforms) == len(children) * (sc.steps + 1)  # every epoch, once each
    for s in read_topic(bag, topics.PLATFORM_STATES, PlatformState):
        t = transforms[(f"platform/{s.platform_id}", _ns(s.header.stamp))].transform
        assert (t.translation.x, t.translation.y) == (s.position.x, s.position.y)
        assert _yaw(t.rotation) == pytest.approx(s.heading, abs=1e-12)
    for g in read_topic(bag, topics.GROUND_TRUTH, GroundTruthArray):
        assert list(g.target_ids) == [target]
        (p,), (v,) = g.positions, g.velocities
        t = transforms[(f"target/{target}/truth", _ns(g.header.stamp))].transform
        assert (t.translation.x, t.translation.y) == (p.x, p.y)
        course = math.atan2(v.y, v.x)
        assert _yaw(t.rotation) == pytest.approx(course, abs=1e-12)
    arrays = read_topic(bag, topics.TRACKS, TrackArray)
    for k in arrays:
        (track,) = k.tracks
        assert track.origin == target  # the track from the target's prior: its frame
        t = transforms[(f"target/{target}/estimate", _ns(k.header.stamp))].transform
        x, vx, y, vy = track.mean  # pv order (docs/core-interfaces.md)
        assert (t.translation.x, t.translation.y) == pytest.approx((x, y), abs=1e-9)
        assert _yaw(t.rotation) == pytest.approx(math.atan2(vy, vx), abs=1e-9)


def test_tf_static_mounts_every_sensor_on_its_platform(bag):
    sc = load_scenario(SCENARIO)
    static = read_topic(bag, topics.TF_STATIC, TFMessage)
    assert len(static) == 1  # one latched message with every static transform
    mounts = {(t.header.frame_id, t.child_frame_id) for t in static[0].transforms}
    assert mounts == {
        (f"platform/{p.id}", f"sensor/{s.id}") for p in sc.platforms for s in p.sensors
    }


def test_every_header_names_the_fixed_frame(bag):
    for topic, cls in (
        (topics.PLATFORM_STATES, PlatformState),
        (topics.TRACKS, TrackArray),
        (topics.SCANS, Scan),
        (topics.GROUND_TRUTH, GroundTruthArray),
    ):
        assert {m.header.frame_id for m in read_topic(bag, topic, cls)} == {"world"}


def test_a_message_in_another_frame_is_rejected_and_counted(graph):
    """A tracker in frame "map" is fed a scan stamped in "world" (e.g. a driver left at the
    default): rejected as wrong_frame, counted, and the node keeps running."""
    params = [Parameter("scenario", value=SCENARIO), Parameter("frame_id", value="map")]
    tracker = graph.add(TrackerNode(context=graph.context, parameter_overrides=params))
    feeder = graph.add(Node("feeder", context=graph.context))
    pub = feeder.create_publisher(Scan, topics.SCANS, qos_for(topics.SCANS))
    msg = Scan(header=header(5.0, "world"), sensor_id="s1", platform_id="p1", epoch=1)
    for _ in range(3):
        pub.publish(msg)
    assert graph.spin_until(
        lambda: tracker.counters.counts.get("rejected.wrong_frame") == 3, timeout=5.0
    )
    assert tracker.counters.total("errors.") == 0 and not tracker.epochs


def test_views_are_built_for_their_readers_only(graph):
    """The views (tf, poses, markers, particles: volatile topics) are built only while their
    topic has a reader: at 30 tracks they were a fifth of a run's time for nobody. A viewer
    that subscribes later gets the next epoch's ellipses and ids, and DELETEs for tracks drawn
    before (as the tracker counts them drawn, read or not) that are gone."""
    params = [Parameter("scenario", value=SCENARIO)]
    tracker = graph.add(TrackerNode(context=graph.context, parameter_overrides=params))
    built = []
    tracker.track_markers = lambda *a, f=tracker.track_markers: built.append(f(*a)) or built[-1]
    prior = tracker.core.snapshot()
    ids = {t.track_id for t in prior.confirmed}
    assert ids  # the scenario's priors: confirmed tracks
    tracker.publish_tracks(prior)
    assert built == [] and tracker.drawn == ids
    seen = []
    graph.add(Node("viewer", context=graph.context)).create_subscription(
        MarkerArray, topics.MARKERS, seen.append, 10
    )
    tracker.publish_tracks(replace(prior, tracks=()))  # every track gone
    assert graph.spin_until(lambda: seen, timeout=5.0)
    deleted = {(m.ns, m.id) for m in seen[0].markers if m.action == Marker.DELETE}
    assert deleted == {(ns, i) for ns in ("tracks", "track_ids") for i in ids}
    assert len(built) == 1 and tracker.drawn == set()
