"""Replay a recorded run's measurements into a fresh tracker and compare the tracks.

With the recorded configuration the replayed track equals the recorded one exactly (the
tracker is deterministic for a seed); with another filter (``--filter``) the report compares
both against the recorded ground truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from rosbags.rosbag2 import Reader

from activetrack_bringup.bag import BagPlayer
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_ros import graph as topics
from activetrack_ros.graph import reader_qos
from msgs_defs.msg import GroundTruth, TrackEstimate
from tracker_node.tracker_node import TrackerNode

MEASUREMENT_TOPICS = (topics.BEARING_MEASUREMENTS, topics.POLAR_MEASUREMENTS)


def read_topic(bag, topic: str, msg_type) -> list:
    """Deserialize every message of one topic of a bag (rclpy, exact)."""
    with Reader(bag) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [deserialize_message(bytes(d), msg_type) for _, _, d in reader.messages(conns)]


class _TrackCollector(Node):
    def __init__(self, **kwargs):
        super().__init__("retrack_collector", **kwargs)
        self.tracks: dict[int, TrackEstimate] = {}
        self.create_subscription(
            TrackEstimate,
            topics.TRACK,
            lambda m: self.tracks.__setitem__(m.epoch, m),
            reader_qos(topics.TRACK),
        )


@dataclass
class RetrackReport:
    epochs: int
    recorded_filter: str
    replayed_filter: str
    max_state_difference: float
    max_covariance_difference: float
    recorded_rmse: tuple[float, float]
    replayed_rmse: tuple[float, float]

    def to_json(self) -> dict:
        return dict(self.__dict__)


def _rmse(tracks: dict, truth: dict) -> tuple[float, float]:
    """RMSE in x and y over the epochs k >= 1 (position entries named x/y or px/py)."""
    ks = sorted(k for k in tracks if k in truth and k > 0)
    names = list(tracks[ks[0]].state_names)
    ix = names.index("x") if "x" in names else names.index("px")
    iy = names.index("y") if "y" in names else names.index("py")
    err = np.array(
        [
            [tracks[k].state[ix] - truth[k].position.x, tracks[k].state[iy] - truth[k].position.y]
            for k in ks
        ]
    )
    return tuple(float(v) for v in np.sqrt((err**2).mean(axis=0)))


def retrack(
    bag,
    scenario_path: str,
    *,
    filter_kind: str | None = None,
    run: int | None = None,
    timeout: float = 300.0,
) -> RetrackReport:
    recorded = {m.epoch: m for m in read_topic(bag, topics.TRACK, TrackEstimate)}
    truth = {m.epoch: m for m in read_topic(bag, topics.GROUND_TRUTH, GroundTruth)}
    params = [
        Parameter("scenario", value=str(scenario_path)),
        Parameter("run", value=-1 if run is None else run),
        Parameter("filter", value=filter_kind or ""),
    ]
    with InProcessGraph() as graph:
        collector = graph.add(_TrackCollector(context=graph.context))
        tracker = graph.add(TrackerNode(context=graph.context, parameter_overrides=params))
        player = graph.add(
            BagPlayer(bag, measurement_topics_in(bag), rate=1e9, context=graph.context)
        )
        last = max(recorded)
        graph.spin_until(
            lambda: (player.play_step(), last in collector.tracks)[1], timeout=timeout, step=0.0
        )
        replayed = dict(collector.tracks)
        rejected = tracker.counters.total_rejected
    if rejected:
        raise RuntimeError(f"the fresh tracker rejected {rejected} replayed measurements")
    common = sorted(set(recorded) & set(replayed))
    ds = max(np.abs(np.subtract(recorded[k].state, replayed[k].state)).max() for k in common)
    dc = (
        max(
            np.abs(np.subtract(recorded[k].covariance, replayed[k].covariance)).max()
            for k in common
        )
        if all(len(recorded[k].covariance) == len(replayed[k].covariance) for k in common)
        else np.nan
    )
    return RetrackReport(
        epochs=len(common),
        recorded_filter=recorded[common[0]].filter_kind,
        replayed_filter=replayed[common[0]].filter_kind,
        max_state_difference=float(ds),
        max_covariance_difference=float(dc),
        recorded_rmse=_rmse(recorded, truth),
        replayed_rmse=_rmse(replayed, truth),
    )


def measurement_topics_in(bag) -> list[str]:
    """The measurement topics a bag holds."""
    with Reader(bag) as reader:
        present = {c.topic for c in reader.connections if c.msgcount}
    return [t for t in MEASUREMENT_TOPICS if t in present]
