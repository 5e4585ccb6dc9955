"""The per-epoch messages of every scene (Scan, TrackArray, BeamCommand, GroundTruthArray) and
their conversions (activetrack_ros.convert): exact round trips through CDR on seeded data for
one target and many, every bad field rejected with a ValueError (and a counted Rejected) that
names it, and the topics in the graph table with the per-epoch QoS."""

from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy
from rclpy.serialization import deserialize_message, serialize_message

from activetrack.closed_loop.components import (
    build_simulator,
    build_tracker,
    scene_sensors,
    scene_targets,
)
from activetrack.data import (
    CONFIRMED,
    TENTATIVE,
    BeamCommand,
    TrackEstimate,
    TrackSet,
    TruthSet,
)
from activetrack.scenarios import load_scenario
from activetrack_ros import graph
from activetrack_ros.convert import (
    MessageError,
    TrackArrayChecker,
    beam_from_msg,
    beam_msg,
    header,
    scan_from_msg,
    scan_msg,
    track_array_from_msg,
    track_array_msg,
    truth_array_from_msg,
    truth_array_msg,
)
from activetrack_ros.node_base import Rejected
from activetrack_ros.trust import is_signed_type

pytestmark = pytest.mark.ros

ROOT = Path(__file__).resolve().parents[2]
MSGS = ROOT / "src" / "msgs_defs"
# One target (the papers' scenes: a bearing sensor pair; range-bearing and range-rate sensors,
# a circular-motion target) and many (clutter, beams, births and deaths).
SCENARIOS = (
    "hernandez_2sensor_single",
    "ramdaras_case3_pd",
    "valverde_circular",
    "mt_bearings_crossing",
    "mt_radars_beams",
    "mt_appear_disappear",
)
LOADED = {name: load_scenario(ROOT / "scenarios" / f"{name}.yaml") for name in SCENARIOS}
NEW_TOPICS = {
    graph.SCANS: "msgs_defs/msg/Scan",
    graph.TRACKS: "msgs_defs/msg/TrackArray",
    graph.BEAM_COMMANDS: "msgs_defs/msg/BeamCommand",
    graph.GROUND_TRUTH: "msgs_defs/msg/GroundTruthArray",
}
# The topics of the former single-target messages (BearingMeasurement, PolarMeasurement,
# Measurement, TrackEstimate): gone from the graph.
FORMER_TOPICS = (
    "activetrack/bearing_measurements",
    "activetrack/polar_measurements",
    "activetrack/measurements",
    "activetrack/track",
)


def _cdr(msg):
    """The message after serialisation and back: what a subscriber or a bag player gets."""
    return deserialize_message(serialize_message(msg), type(msg))


def _close(a, b) -> None:
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-12)


def _simulated(name: str, epochs: int, seed: int = 7):
    """(scenario, [(scans, truth set)] for epochs 1..epochs) of a seeded simulator run."""
    scenario = LOADED[name]
    sim = build_simulator(scenario, np.random.default_rng(seed))
    return scenario, [(sim.advance(), sim.truth_set()) for _ in range(epochs)]


# --- the interface package and the graph table ---------------------------------------------------


def test_message_module_imports_and_cmake_lists_every_msg_file():
    import msgs_defs.msg as module

    files = sorted(p.stem for p in (MSGS / "msg").glob("*.msg"))
    listed = re.findall(r'"msg/(\w+)\.msg"', (MSGS / "CMakeLists.txt").read_text())
    assert sorted(listed) == files
    assert len(listed) == len(set(listed))
    for name in ("Scan", "TrackItem", "TrackArray", "BeamCommand", "GroundTruthArray"):
        assert name in files
    for name in files:
        assert getattr(module, name).__name__ == name  # generated and installed


def test_topics_are_per_epoch_signed_and_latched():
    for topic, msgtype in NEW_TOPICS.items():
        assert graph.GRAPH_TOPICS[topic] == msgtype
        assert topic in graph.LATCHED_TOPICS
        assert graph.graph_topic_of(f"/g1/{topic}") == topic
        w = graph.writer_qos(topic, depth=123)
        assert (w.depth, w.reliability, w.durability) == (
            123,
            ReliabilityPolicy.RELIABLE,
            DurabilityPolicy.TRANSIENT_LOCAL,
        )
        r = graph.reader_qos(topic)
        assert (r.history, r.durability) == (
            HistoryPolicy.KEEP_ALL,
            DurabilityPolicy.TRANSIENT_LOCAL,
        )
        package, _, name = msgtype.split("/")
        assert is_signed_type(getattr(__import__(f"{package}.msg").msg, name))
    # One message family: the former measurement and track topics are no graph topics.
    assert graph.graph_topic_of("/activetrack/tracks") == graph.TRACKS
    assert graph.graph_topic_of("/activetrack/ground_truth") == graph.GROUND_TRUTH
    for topic in FORMER_TOPICS:
        assert topic not in graph.GRAPH_TOPICS
        assert graph.graph_topic_of("/" + topic) is None


# --- round trips ---------------------------------------------------------------------------------


@pytest.mark.parametrize("name", SCENARIOS)
def test_scans_and_truth_round_trip_exactly(name):
    scenario, epochs = _simulated(name, 12)
    sensors = scene_sensors(scenario)
    detections = 0
    ids_seen = set()
    for scans, truth in epochs:
        for scan in scans:
            msg = _cdr(scan_msg(scan, scenario, len(scans), sensors=sensors))
            assert (msg.dim, msg.epoch_scan_count) == (sensors[scan.sensor_id][1].dim_z, len(scans))
            back = scan_from_msg(msg, scenario)
            assert (back.sensor_id, back.epoch, back.time) == (
                scan.sensor_id,
                scan.epoch,
                scan.time,
            )
            _close(back.Z, scan.Z)
            _close(back.sensor_pv, scan.sensor_pv)
            assert back.fov == scan.fov
            detections += len(scan.Z)
        back_truth = truth_array_from_msg(_cdr(truth_array_msg(truth)), scenario)
        assert (back_truth.epoch, back_truth.time, back_truth.ids) == (
            truth.epoch,
            truth.time,
            truth.ids,
        )
        _close(back_truth.pv, truth.pv)
        assert back_truth.state_names == truth.state_names
        for x, y in zip(back_truth.states, truth.states, strict=True):
            _close(x, y)
        ids_seen.add(truth.ids)
    # Scans with detections were compared (one target: at most one per scan).
    assert detections >= (2 if name.startswith("mt_") else 1) * len(epochs)
    if name == "mt_appear_disappear":
        assert len(ids_seen) >= 2  # targets born or died within the window


def _random_tracks(rng: np.random.Generator, n: int, epoch: int, scenario) -> TrackSet:
    """``n`` random tracks in the scenario tracker's state (its filter, motion model and
    state names); odd ones carry particle samples."""
    check = TrackArrayChecker(scenario)
    dim = len(check.state_names)
    tracks = []
    for i in range(n):
        A = rng.standard_normal((4, 4)) * [30.0, 2.0, 30.0, 2.0]
        B = rng.standard_normal((dim, dim))
        pf = i % 2 == 1
        tracks.append(
            TrackEstimate(
                track_id=int(3 * i + 1),
                status=CONFIRMED if i % 3 else TENTATIVE,
                mean=rng.normal(0.0, 1e3, 4),
                cov=A @ A.T + np.eye(4),
                state=rng.normal(0.0, 1e3, dim),
                state_cov=B @ B.T + np.eye(dim),
                origin="t1" if i == 0 else "",
                priority=float(rng.uniform(0.5, 3.0)),
                age=int(rng.integers(0, 50)),
                hits=int(rng.integers(0, 20)),
                misses=int(rng.integers(0, 20)),
                missed_detections=int(rng.integers(0, 20)),
                existence=float(rng.uniform(0.0, 1.0)),
                nis=math.nan if pf else float(rng.uniform(0.0, 9.0)),
                ess=float(rng.uniform(10, 500)) if pf else math.nan,
                particle_count=1000 if pf else 0,
                samples=rng.normal(0.0, 1e3, (int(rng.integers(1, 60)), dim)) if pf else None,
                withheld=bool(i % 3 == 2),  # confirmed tracks left out of the estimate
            )
        )
    return TrackSet(
        epoch=epoch,
        time=epoch * scenario.dt,
        filter_kind=scenario.tracker.filter,
        motion_model=check.motion_model,
        state_names=check.state_names,
        tracks=tuple(tracks),
        updates=max(epoch - 1, 0),
        detections=9,
        unassociated=4,
    )


_FIELDS = (
    "track_id", "status", "origin", "priority", "age", "hits", "misses", "missed_detections",
    "existence", "particle_count", "withheld",
)  # fmt: skip


def _same_float(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def _assert_same_tracks(back: TrackSet, tracks: TrackSet) -> None:
    assert (back.epoch, back.time, back.filter_kind, back.motion_model, back.state_names) == (
        tracks.epoch,
        tracks.time,
        tracks.filter_kind,
        tracks.motion_model,
        tracks.state_names,
    )
    assert (back.updates, back.detections, back.unassociated) == (
        tracks.updates,
        tracks.detections,
        tracks.unassociated,
    )
    assert len(back.tracks) == len(tracks.tracks)
    for b, t in zip(back.tracks, tracks.tracks, strict=True):
        assert [getattr(b, f) for f in _FIELDS] == [getattr(t, f) for f in _FIELDS]
        assert _same_float(b.ess, t.ess) and _same_float(b.nis, t.nis)
        _close(b.mean, t.mean)
        _close(b.cov, t.cov)
        _close(b.state, t.state)
        _close(b.state_cov, t.state_cov)
        assert (b.samples is None) == (t.samples is None)
        if t.samples is not None:
            _close(b.samples, t.samples)


@pytest.mark.parametrize("name", ["valverde_circular", "mt_bearings_crossing"])
def test_seeded_track_arrays_round_trip_exactly(name):
    scenario = LOADED[name]
    rng = np.random.default_rng(2024)
    for epoch, n in ((0, 0), (3, 1), (17, 7)):
        tracks = _random_tracks(rng, n, epoch, scenario)
        msg = _cdr(track_array_msg(tracks))
        assert [t.status for t in msg.tracks] == [
            1 if t.status == CONFIRMED else 0 for t in tracks.tracks
        ]
        _assert_same_tracks(track_array_from_msg(msg, scenario), tracks)


@pytest.mark.parametrize("name", ["valverde_circular", "mt_appear_disappear"])
def test_tracker_output_round_trips_with_particle_samples(name):
    base = LOADED[name]
    cfg = base.tracker.model_copy(update={"filter": "pf", "particles": 300, "planner_samples": 40})
    scenario = base.model_copy(update={"tracker": cfg})
    sim = build_simulator(scenario, np.random.default_rng(11))
    tracker = build_tracker(scenario, np.random.default_rng(12))
    for k in range(1, 9):
        tracks = tracker.step(k, k * scenario.dt, sim.advance())
        _assert_same_tracks(track_array_from_msg(_cdr(track_array_msg(tracks)), scenario), tracks)
    dim = len(tracks.state_names)
    assert tracks.tracks and all(t.samples.shape == (40, dim) for t in tracks.tracks)


def test_beams_round_trip_exactly():
    scenario = LOADED["mt_radars_beams"]
    rng = np.random.default_rng(5)
    for sensor_id in ("s1", "s2", "s3"):
        for epoch in (0, 17, scenario.steps - 1):
            beam = BeamCommand(
                sensor_id, epoch, float(rng.uniform(-10, 10)), int(rng.integers(-1, 9))
            )
            back = beam_from_msg(_cdr(beam_msg(beam, scenario.dt)), scenario)
            assert (back.sensor_id, back.epoch, back.track_id) == (
                beam.sensor_id,
                beam.epoch,
                beam.track_id,
            )
            _close(back.bearing, beam.bearing)


# --- rejections ----------------------------------------------------------------------------------


def _scan(name: str = "mt_appear_disappear", sensor: str = "surv1"):
    scenario, epochs = _simulated(name, 3, seed=3)
    scans = epochs[-1][0]
    scan = next(s for s in scans if s.sensor_id == sensor and len(s.Z))
    return scenario, scan_msg(scan, scenario, len(scans))


def _set(msg, path: str, value):
    *parents, leaf = path.split(".")
    setattr(_get(msg, ".".join(parents)) if parents else msg, leaf, value)


def _expect(call, reason: str, field: str) -> None:
    with pytest.raises(ValueError, match=re.escape(field)) as info:
        call()
    assert isinstance(info.value, Rejected) and isinstance(info.value, MessageError)
    assert info.value.reason == reason


def _with_detection(msg, row: int, column: int, value: float):
    values = list(msg.detections)
    values[row * msg.dim + column] = value
    return values


SCAN_CASES = [
    (
        "nan_detection",
        lambda m: _set(m, "detections", _with_detection(m, 0, 1, math.nan)),
        "non_finite",
        "detections",
    ),
    (
        "inf_range",
        lambda m: _set(m, "detections", _with_detection(m, 0, 0, math.inf)),
        "non_finite",
        "detections",
    ),
    (
        "bearing_4_rad",
        lambda m: _set(m, "detections", _with_detection(m, 0, 1, 4.0)),
        "out_of_range",
        "detections (bearing)",
    ),
    ("unknown_sensor", lambda m: _set(m, "sensor_id", "sonar9"), "unknown_sensor", "sensor_id"),
    ("wrong_dim", lambda m: _set(m, "dim", 1), "wrong_dimension", "dim must be 2"),
    (
        "ragged",
        lambda m: _set(m, "detections", list(m.detections)[:-1]),
        "wrong_dimension",
        "detections must hold a multiple of dim",
    ),
    (
        "stamp_off",
        lambda m: _set(m, "header.stamp.sec", m.header.stamp.sec + 1),
        "bad_stamp",
        "stamp",
    ),
    (
        "nanosec_overflow",
        lambda m: _set(m, "header.stamp.nanosec", 10**9),
        "bad_stamp",
        "header.stamp",
    ),
    ("future_epoch", lambda m: _set(m, "epoch", 10**6), "future_epoch", "epoch"),
    (
        "epoch_zero",
        lambda m: (_set(m, "epoch", 0), _set(m, "header.stamp.sec", 0)),
        "out_of_order",
        "epoch must be >= 1",
    ),
    ("fov_width_zero", lambda m: _set(m, "fov_width", 0.0), "out_of_range", "fov_width"),
    ("fov_width_over_2pi", lambda m: _set(m, "fov_width", 7.0), "out_of_range", "fov_width"),
    ("fov_not_the_sensors", lambda m: _set(m, "fov_centre", 1.0), "sensor_mismatch", "fov_centre"),
    ("fov_r_max_nan", lambda m: _set(m, "fov_r_max", math.nan), "out_of_range", "fov_r_max"),
    (
        "R_not_the_sensors",
        lambda m: _set(m, "covariance", [3600.0, 0.0, 0.0, 1e-3]),
        "sensor_mismatch",
        "covariance",
    ),
    ("R_wrong_size", lambda m: _set(m, "covariance", [1.0]), "bad_covariance", "covariance"),
    ("other_platform", lambda m: _set(m, "platform_id", "p2"), "inconsistent", "platform_id"),
    ("other_kind", lambda m: _set(m, "sensor_kind", "bearing"), "wrong_sensor_kind", "sensor_kind"),
    (
        "clutter_density",
        lambda m: _set(m, "clutter_density", 1.0),
        "sensor_mismatch",
        "clutter_density",
    ),
    ("scan_count", lambda m: _set(m, "epoch_scan_count", 4), "out_of_range", "epoch_scan_count"),
    (
        "nan_sensor_position",
        lambda m: _set(m, "sensor_position.x", math.nan),
        "non_finite",
        "sensor position",
    ),
]


@pytest.mark.parametrize(
    "mutate, reason, field", [c[1:] for c in SCAN_CASES], ids=[c[0] for c in SCAN_CASES]
)
def test_bad_scans_are_rejected_naming_the_field(mutate, reason, field):
    scenario, msg = _scan()
    assert scan_from_msg(msg, scenario).Z.shape[1] == 2  # valid before the change
    mutate(msg)
    _expect(lambda: scan_from_msg(_cdr(msg), scenario), reason, field)


def test_a_beam_scan_must_be_pointed_where_its_field_of_view_says():
    scenario, msg = _scan("mt_radars_beams", "s2")
    for centre in (-3.0, 0.4, math.pi):  # a beam may point anywhere: the message says where
        msg.fov_centre = centre
        assert scan_from_msg(msg, scenario).fov.centre == centre
    msg.fov_width = 0.2  # but its width is the sensor's beam_width (0.1)
    _expect(lambda: scan_from_msg(msg, scenario), "sensor_mismatch", "fov_width")


def _tracks_msg():
    scenario = LOADED["mt_appear_disappear"]
    tracks = _random_tracks(np.random.default_rng(9), 4, 6, scenario)
    return scenario, track_array_msg(tracks)


def _track(i: int, path: str, value):
    return lambda m: _set(m.tracks[i], path, value)


NOT_SPD = np.diag([1.0, 1.0, -1.0, 1.0]).ravel()
ASYMMETRIC = (np.eye(4) + np.triu(np.ones((4, 4)), 1)).ravel()
TRACK_CASES = [
    (
        "not_positive_definite",
        _track(1, "covariance", NOT_SPD),
        "bad_covariance",
        "covariance is not positive definite",
    ),
    (
        "asymmetric",
        _track(2, "covariance", ASYMMETRIC),
        "bad_covariance",
        "covariance is not symmetric",
    ),
    ("nan_covariance", _track(0, "covariance", np.full(16, math.nan)), "non_finite", "covariance"),
    ("nan_mean", _track(3, "mean", np.array([0.0, math.nan, 0.0, 0.0])), "non_finite", "mean"),
    ("status", _track(0, "status", 7), "bad_field", "status"),
    ("origin", _track(0, "origin", "t99"), "bad_field", "origin"),
    ("priority", _track(0, "priority", 0.0), "out_of_range", "priority"),
    ("samples_ragged", _track(1, "samples", [1.0, 2.0, 3.0]), "wrong_dimension", "sample_count"),
    ("duplicate_id", _track(1, "track_id", 1), "bad_field", "track_id"),
    ("filter_kind", lambda m: _set(m, "filter_kind", "pf"), "bad_field", "filter_kind"),
    ("stamp", lambda m: _set(m, "header.stamp.sec", 1), "bad_stamp", "stamp"),
    ("unassociated", lambda m: _set(m, "unassociated", 10), "out_of_range", "unassociated"),
    ("nan_state", _track(0, "state", [0.0, math.nan, 0.0, 0.0]), "non_finite", "state"),
    ("state_length", _track(2, "state", [0.0] * 3), "wrong_dimension", "state must have 4"),
    (
        "state_covariance_not_positive_definite",
        _track(1, "state_covariance", NOT_SPD),
        "bad_covariance",
        "covariance is not positive definite",
    ),
    ("existence", _track(0, "existence", 1.5), "out_of_range", "existence"),
    ("withheld_tentative", _track(0, "withheld", True), "bad_field", "withheld"),
    ("nis_inf", _track(0, "nis", math.inf), "non_finite", "nis"),
    (
        "motion_model",
        lambda m: _set(m, "motion_model", "circular"),
        "wrong_dimension",
        "motion_model",
    ),
    (
        "state_names",
        lambda m: _set(m, "state_names", ["x", "y", "vx", "vy"]),
        "wrong_dimension",
        "state_names",
    ),
]


@pytest.mark.parametrize(
    "mutate, reason, field", [c[1:] for c in TRACK_CASES], ids=[c[0] for c in TRACK_CASES]
)
def test_bad_track_arrays_are_rejected_naming_the_field(mutate, reason, field):
    scenario, msg = _tracks_msg()
    assert len(track_array_from_msg(msg, scenario).tracks) == 4
    mutate(msg)
    _expect(lambda: track_array_from_msg(_cdr(msg), scenario), reason, field)


@pytest.mark.parametrize(
    ("faults", "reason", "field"),
    [
        ((_track(1, "covariance", NOT_SPD), _track(2, "status", 7)), "bad_covariance", "{1}"),
        ((_track(1, "status", 7), _track(2, "covariance", NOT_SPD)), "bad_field", "{1}: status"),
        (
            (_track(1, "covariance", NOT_SPD), _track(3, "mean", [math.nan] * 4)),
            "bad_covariance",
            "{1}",
        ),
        (
            (_track(2, "state_covariance", NOT_SPD), _track(2, "covariance", ASYMMETRIC)),
            "bad_covariance",
            "{2} covariance is not symmetric",
        ),
    ],
)
def test_the_first_fault_of_a_track_array_is_the_one_named(faults, reason, field):
    """The covariances of all items are checked at once after the items' other fields: the
    error is still the first one in the items' order (an item's covariance, then its state
    covariance, before the next item's fields)."""
    scenario, msg = _tracks_msg()
    ids = [item.track_id for item in msg.tracks]
    for fault in faults:
        fault(msg)
    field = field.format(*(f"track {i}" for i in ids))
    _expect(lambda: track_array_from_msg(_cdr(msg), scenario), reason, field)


def test_too_many_samples_and_tracks_are_refused():
    scenario, msg = _tracks_msg()
    n = scenario.tracker.planner_samples + 1
    msg.tracks[1].samples, msg.tracks[1].sample_count = [0.0] * (4 * n), n
    _expect(
        lambda: track_array_from_msg(msg, scenario), "wrong_dimension", "sample_count must be <="
    )
    scenario, msg = _tracks_msg()
    most = scenario.tracker.tracks.max_tracks + len(scene_targets(scenario))
    msg.tracks = [msg.tracks[0]] * (most + 1)
    _expect(
        lambda: track_array_from_msg(msg, scenario),
        "out_of_range",
        f"tracks must hold at most {most}",
    )


def _at_epoch(msg, epoch: int) -> None:
    """Move a beam command of mt_appear_disappear to ``epoch``, stamped consistently."""
    msg.epoch = epoch
    msg.header = header(epoch * LOADED["mt_appear_disappear"].dt)


BEAM_CASES = [
    ("nan_bearing", "trk1", lambda m: _set(m, "bearing", math.nan), "non_finite", "bearing"),
    ("huge_bearing", "trk1", lambda m: _set(m, "bearing", 1e9), "out_of_range", "bearing"),
    ("not_steerable", "surv1", None, "unknown_sensor", "sensor_id must be a steerable sensor"),
    ("unknown_sensor", "x", None, "unknown_sensor", "sensor_id"),
    (
        "last_epoch",
        "trk2",
        lambda m: _at_epoch(m, LOADED["mt_appear_disappear"].steps),
        "future_epoch",
        "epoch must be <",
    ),
    ("stamp", "trk2", lambda m: _set(m, "header.stamp.nanosec", 5000), "bad_stamp", "stamp"),
    ("track_id", "trk2", lambda m: _set(m, "track_id", -2), "out_of_range", "track_id"),
]


@pytest.mark.parametrize(
    "sensor, mutate, reason, field", [c[1:] for c in BEAM_CASES], ids=[c[0] for c in BEAM_CASES]
)
def test_bad_beam_commands_are_rejected_naming_the_field(sensor, mutate, reason, field):
    scenario = LOADED["mt_appear_disappear"]
    msg = beam_msg(BeamCommand(sensor, 4, 0.5, 2), scenario.dt)
    if mutate is not None:
        assert beam_from_msg(msg, scenario).bearing == 0.5
        mutate(msg)
    _expect(lambda: beam_from_msg(_cdr(msg), scenario), reason, field)


def _truth_msg():
    scenario = LOADED["mt_bearings_crossing"]
    pv = np.arange(12.0).reshape(3, 4)
    names = (("x", "xdot", "y", "ydot"),) * 3
    truth = TruthSet(2, 2 * scenario.dt, ("t1", "t2", "t3"), pv, tuple(pv), names)
    return scenario, truth_array_msg(truth)


TRUTH_CASES = [
    (
        "unknown_target",
        lambda m: _set(m, "target_ids", ["t1", "t9", "t3"]),
        "bad_field",
        "target_ids",
    ),
    (
        "out_of_order",
        lambda m: _set(m, "target_ids", ["t2", "t1", "t3"]),
        "bad_field",
        "target_ids",
    ),
    ("duplicate", lambda m: _set(m, "target_ids", ["t1", "t1", "t3"]), "bad_field", "target_ids"),
    ("lengths", lambda m: _set(m, "velocities", m.velocities[:2]), "wrong_dimension", "velocities"),
    (
        "nan_position",
        lambda m: _set(m.positions[1], "y", math.nan),
        "non_finite",
        "target t2 position",
    ),
    ("stamp", lambda m: _set(m, "header.stamp.sec", 0), "bad_stamp", "stamp"),
]


@pytest.mark.parametrize(
    "mutate, reason, field", [c[1:] for c in TRUTH_CASES], ids=[c[0] for c in TRUTH_CASES]
)
def test_bad_truth_arrays_are_rejected_naming_the_field(mutate, reason, field):
    scenario, msg = _truth_msg()
    _close(truth_array_from_msg(msg, scenario).pv, np.arange(12.0).reshape(3, 4))
    mutate(msg)
    _expect(lambda: truth_array_from_msg(_cdr(msg), scenario), reason, field)


def test_conversions_to_messages_refuse_what_no_message_can_say():
    _, epochs = _simulated("mt_bearings_crossing", 1)
    with pytest.raises(ValueError, match="sensor_id"):
        scan_msg(epochs[0][0][0], LOADED["mt_radars_beams"].model_copy(update={"platforms": []}))
    bad = TrackEstimate(1, "lost", np.zeros(4), np.eye(4), np.zeros(4), np.eye(4))
    with pytest.raises(ValueError, match="status"):
        track_array_msg(TrackSet(0, 0.0, "ekf", "ncv", tracks=(bad,)))


# --- nothing but a counted rejection --------------------------------------------------------------

BAD_VALUES = {
    "double": [math.nan, math.inf, -math.inf, 1e300, -1.0, 0.0, 5e-324],
    "uint32": [0, 1, 2**32 - 1],
    "uint8": [0, 2, 255],
    "int64": [-(2**63), -2, 2**63 - 1],
    "int32": [-(2**31), -1, 2**31 - 1],
    "string": ["", "x", "s1", "t1", "é" * 50],
    "boolean": [True, False],
}


def _leaves(msg, prefix: str = ""):
    """(path, type) of every field but the trailer, into nested messages and their arrays."""
    for name, kind in msg.get_fields_and_field_types().items():
        value = getattr(msg, name)
        if hasattr(value, "get_fields_and_field_types"):
            yield from _leaves(value, f"{prefix}{name}.")
        elif (
            kind.startswith("sequence<")
            and value
            and hasattr(value[0], "get_fields_and_field_types")
        ):
            yield prefix + name, kind
            for i, item in enumerate(value):
                yield from _leaves(item, f"{prefix}{name}.{i}.")
        elif name != "graph_auth":
            yield prefix + name, kind


def _get(msg, path: str):
    for p in path.split("."):
        msg = msg[int(p)] if p.isdigit() else getattr(msg, p)
    return msg


def _bad_value(value, kind: str, rng: np.random.Generator):
    """A bad value for a field of type ``kind`` holding ``value``."""
    if kind in BAD_VALUES:
        options = BAD_VALUES[kind]
        return options[rng.integers(len(options))]
    items = list(value)
    if kind.startswith("double["):  # fixed size: one bad entry
        items[rng.integers(len(items))] = BAD_VALUES["double"][rng.integers(7)]
        return np.array(items)
    extra = {"sequence<double>": math.nan, "sequence<string>": "t9"}.get(kind)
    choice = rng.integers(3 if extra is not None else 2)
    return [[], items[:-1], [*items, extra]][choice]


def _mutations(msg, rng: np.random.Generator, count: int):
    """``count`` copies of ``msg``, each with one random field set to a bad value (NaN, inf,
    huge, negative, unknown ids, truncated or extended arrays)."""
    leaves = list(_leaves(msg))
    for _ in range(count):
        copy = _cdr(msg)
        path, kind = leaves[rng.integers(len(leaves))]
        *parents, leaf = path.split(".")
        owner = _get(copy, ".".join(parents)) if parents else copy
        setattr(owner, leaf, _bad_value(getattr(owner, leaf), kind, rng))
        yield copy


def test_random_bad_fields_give_only_message_errors():
    """A member of the graph with bad data (a bug) must be counted, never crash a node."""
    rng = np.random.default_rng(99)
    scenario_s, scan = _scan()
    scenario_t, tracks = _tracks_msg()
    scenario_b = LOADED["mt_appear_disappear"]
    beam = beam_msg(BeamCommand("trk1", 3, 0.2, 1), scenario_b.dt)
    scenario_g, truth = _truth_msg()
    cases = [
        (scan, scan_from_msg, scenario_s),
        (tracks, track_array_from_msg, scenario_t),
        (beam, beam_from_msg, scenario_b),
        (truth, truth_array_from_msg, scenario_g),
    ]
    for msg, convert, scenario in cases:
        rejected = accepted = 0
        for bad in _mutations(msg, rng, 150):
            try:
                convert(bad, scenario)
                accepted += 1
            except MessageError:
                rejected += 1
        # Both outcomes exercised (seeded: 63..104 of 150 rejected per type).
        assert rejected >= 40 and accepted >= 20, (type(msg).__name__, rejected, accepted)
