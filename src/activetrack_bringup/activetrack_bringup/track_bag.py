"""Bags for ``activetrack track`` (docs/track-your-data.md): its detections (and truth) read from
a rosbag2 of ``Scan`` messages (:func:`activetrack_bringup.retrack.read_run`'s refusals, every
scan checked against the configuration's sensor by ``scan_from_msg``), and its result written
as the recorder's format: per epoch k, at log time k dt, the truth, a ``PlatformState`` per
platform (synthesised from the scans: :func:`platform_states`), the scans and the track array.
"""

from __future__ import annotations

import bisect
from pathlib import Path

import numpy as np
from rclpy.serialization import serialize_message

from activetrack.closed_loop.recorded import TrackingRun
from activetrack.data import PlatformSnapshot, Scan, TruthSet, heading_speed
from activetrack.scenarios.tracking import TrackingConfig
from activetrack.tracking.detections import Detections, SensorTable, truth_set
from activetrack_bringup.bag import bag_qos, graph_schemas
from activetrack_bringup.bag_io import BagError, Rosbag2Writer, TopicSpec
from activetrack_bringup.retrack import read_run
from activetrack_ros import graph as topics
from activetrack_ros.convert import (
    MessageError,
    check_epoch_stamp,
    platform_state_msg,
    pv_of,
    scan_from_msg,
    scan_msg,
    track_array_msg,
    truth_array_msg,
)
from activetrack_ros.graph import GRAPH_TOPICS, MAX_HISTORY_DEPTH

__all__ = ["platform_states", "read_bag", "read_bag_truth", "write_track_bag"]


def read_bag(
    bag, config: TrackingConfig, sensors: SensorTable, skip_damaged: bool = False
) -> tuple[Detections, dict[int, TruthSet] | None]:
    """The bag's scans (by epoch, in the configuration's sensor order) and its truth (None
    without a ground_truth topic); BagError (one line) for a bag or message that does not fit
    the configuration, or for a truncated bag unless ``skip_damaged`` (then its epochs up to
    the cut)."""
    run = read_run(bag, use="track", skip_damaged=skip_damaged)
    order = {sid: i for i, sid in enumerate(sensors)}
    by_epoch: dict[int, list[Scan]] = {}
    rows: dict[tuple[int, str], str] = {}
    for n, msg in enumerate(run.messages[topics.SCANS]):
        try:
            scan = scan_from_msg(msg, config, sensors)
        except MessageError as exc:
            raise BagError(f"{bag}: {topics.SCANS} message {n}: {exc.detail}") from None
        key = (scan.epoch, scan.sensor_id)
        if key in rows:
            raise BagError(
                f"{bag}: {topics.SCANS} message {n}: a second scan of {scan.sensor_id!r} at "
                f"epoch {scan.epoch} (the first: {rows[key]})"
            )
        rows[key] = f"{topics.SCANS} message {n}"
        by_epoch.setdefault(scan.epoch, []).append(scan)
    if not by_epoch:
        raise BagError(f"{bag} holds no scans ({topics.SCANS}): nothing to track")
    scans = {
        k: tuple(sorted(v, key=lambda s: order[s.sensor_id])) for k, v in sorted(by_epoch.items())
    }
    return Detections(str(bag), scans, rows), _bag_truth(bag, run, config)


def read_bag_truth(
    bag, config: TrackingConfig, skip_damaged: bool = False
) -> dict[int, TruthSet] | None:
    """The truth of a bag's ``ground_truth`` topic (None without one); a truncated bag as in
    :func:`read_bag`."""
    return _bag_truth(bag, read_run(bag, use="track", skip_damaged=skip_damaged), config)


def _bag_truth(bag, run, config: TrackingConfig) -> dict[int, TruthSet] | None:
    if not run.messages[topics.GROUND_TRUTH]:
        return None
    truth = {}
    for n, msg in enumerate(run.messages[topics.GROUND_TRUTH]):
        try:
            truth[msg.epoch] = _truth(msg, config)
        except MessageError as exc:
            raise BagError(f"{bag}: {topics.GROUND_TRUTH} message {n}: {exc.detail}") from None
    return truth


def _truth(msg, config: TrackingConfig) -> TruthSet:
    """A GroundTruthArray's targets (ids and pv; the models' own states are not needed)."""
    what = f"truth array epoch {msg.epoch}"
    check_epoch_stamp(msg, config, what)
    ids = list(msg.target_ids)
    if len(set(ids)) != len(ids) or not len(msg.positions) == len(msg.velocities) == len(ids):
        raise MessageError(
            "bad_field", f"{what}: distinct target_ids, one position and velocity each"
        )
    by_id = {
        i: pv_of(p, v, f"{what} target {i!r}")
        for i, p, v in zip(ids, msg.positions, msg.velocities, strict=True)
    }
    return truth_set(msg.epoch, msg.epoch * config.dt, by_id)


def platform_states(
    config: TrackingConfig, detections: Detections
) -> tuple[dict[int, list[PlatformSnapshot]], list[str]]:
    """Each platform's state at epochs 1..K: where its sensors' scans say at the epochs it
    scanned, elsewhere on the constant-velocity line of its nearest scan; and a warning per
    platform that never scanned (it has no state)."""
    dt, K = config.dt, detections.last_epoch
    platform_of = {s.id: p.id for p in config.platforms for s in p.sensors}
    seen: dict[str, dict[int, np.ndarray]] = {p.id: {} for p in config.platforms}
    for k, scans in detections.scans.items():
        for scan in scans:
            seen[platform_of[scan.sensor_id]].setdefault(k, np.asarray(scan.sensor_pv, float))
    states: dict[int, list[PlatformSnapshot]] = {k: [] for k in range(1, K + 1)}
    warnings = []
    for p in config.platforms:
        known = seen[p.id]
        if not known:
            warnings.append(
                f"platform {p.id!r} has no scan in the data: the bag holds no state of it (a "
                "tracker_node closes each epoch after its epoch_timeout)"
            )
            continue
        epochs = sorted(known)
        ids, kinds = tuple(s.id for s in p.sensors), tuple(s.kind for s in p.sensors)
        for k in range(1, K + 1):
            i = bisect.bisect_right(epochs, k)  # epochs[i - 1] <= k < epochs[i]
            before, after = epochs[max(i - 1, 0)], epochs[min(i, len(epochs) - 1)]
            j = before if before <= k and k - before <= abs(after - k) else after
            pv = known[j] + (k - j) * dt * np.array([known[j][1], 0.0, known[j][3], 0.0])
            heading, speed = heading_speed(pv)
            states[k].append(PlatformSnapshot(p.id, k, k * dt, pv, heading, speed, ids, kinds))
    return states, warnings


def write_track_bag(
    path: str | Path,
    config: TrackingConfig,
    sensors: SensorTable,
    detections: Detections,
    run: TrackingRun,
    truth: dict[int, TruthSet] | None = None,
) -> list[str]:
    """The scans, platform states, track arrays and truth as a rosbag2 directory (module
    docstring); the warnings (platforms without a state). BagError if ``path`` exists."""
    states, warnings = platform_states(config, detections)
    used = [topics.SCANS, topics.PLATFORM_STATES, topics.TRACKS]
    if truth is not None:
        used.insert(0, topics.GROUND_TRUTH)
    K = run.epochs
    depth = min(topics.run_history(config, K), MAX_HISTORY_DEPTH)
    schemas = graph_schemas(GRAPH_TOPICS[t] for t in used)
    specs = [
        TopicSpec("/" + t, GRAPH_TOPICS[t], *schemas[GRAPH_TOPICS[t]], qos=bag_qos(t, depth))
        for t in used
    ]
    writer = Rosbag2Writer(path, specs, state="recording")
    try:
        for k in range(K + 1):
            count = len(detections.at(k))
            messages = []
            if truth is not None and k in truth:
                messages.append((topics.GROUND_TRUTH, truth_array_msg(truth[k])))
            messages += [
                (topics.PLATFORM_STATES, platform_state_msg(s, count, topics.FIXED_FRAME))
                for s in states.get(k, ())
            ]
            messages += [
                (topics.SCANS, scan_msg(s, config, count, sensors=sensors))
                for s in detections.at(k)
            ]
            messages.append((topics.TRACKS, track_array_msg(run.track_sets[k])))
            for topic, msg in messages:
                stamp = msg.header.stamp
                log_time = stamp.sec * 1_000_000_000 + stamp.nanosec
                writer.write(writer.channel_ids["/" + topic], log_time, serialize_message(msg))
    except BaseException:
        writer.abandon()
        raise
    writer.close()
    return warnings
