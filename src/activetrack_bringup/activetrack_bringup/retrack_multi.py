"""Replay a recorded multi-target run's scans into a fresh ``multi_tracker_node`` and compare
its track arrays with the recorded ones (``activetrack bag retrack`` on a ``targets:``
scenario).

The tracker is deterministic for a seed, so with the recorded scenario and run the replayed
tracks equal the recorded ones exactly (ids, status, means, covariances); both are scored
against the recorded truth with the scenario's GOSPA. The player publishes each epoch's
recorded platform states and scans (their bytes, re-signed with the replay's own key) once the
track array of the epoch before is out, as the simulator does in lockstep. A bag of another
scenario fails before anything spins with one line (:class:`RetrackError`).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message

from activetrack.metrics import gospa
from activetrack.multitarget.data import TrackSet
from activetrack.scenarios import load_scenario
from activetrack_bringup.bag import bag_topic
from activetrack_bringup.bag_io import open_bag
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_bringup.retrack import STALL_TIMEOUT, RetrackError, _trouble
from activetrack_ros import graph as topics
from activetrack_ros.convert_multi import track_array_from_msg, truth_array_from_msg
from activetrack_ros.graph import GRAPH_TOPICS, writer_qos
from activetrack_ros.node_base import GraphNode
from activetrack_ros.trust import GraphKey
from msgs_defs.msg import GroundTruthArray, PlatformState, TrackArray
from msgs_defs.msg import Scan as ScanMsg
from tracker_node.multi_tracker_node import MultiTrackerNode

_CLASSES = {
    topics.PLATFORM_STATES: PlatformState,
    topics.SCANS: ScanMsg,
    topics.TRACKS: TrackArray,
    topics.GROUND_TRUTH_ARRAY: GroundTruthArray,
}
_REPLAYED = (topics.PLATFORM_STATES, topics.SCANS)  # in this order within an epoch


@dataclass
class MultiRetrackReport:
    epochs: int
    identical: bool  # every replayed track array equals the recorded one (ids, status, numbers)
    max_mean_difference: float  # over tracks of the same id (inf: the track sets differ)
    recorded_gospa: float  # time-averaged over epochs 1..epochs, against the recorded truth
    replayed_gospa: float
    warnings: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        return dict(self.__dict__)


def _read(bag) -> dict[str, list[tuple[object, bytes]]]:
    """Each needed topic's messages (deserialized, with their bytes)."""
    out: dict[str, list[tuple[object, bytes]]] = {}
    with open_bag(bag) as b:
        if b.lost:
            raise RetrackError(f"{b.lost[0]}: retrack needs every scan of the run")
        for topic, cls in _CLASSES.items():
            name = bag_topic(b, topic)
            t = b.topics.get(name) if name else None
            out[topic] = []
            if t is None or not t.count:
                continue
            if t.problem or t.msgtype != GRAPH_TOPICS[topic]:
                raise RetrackError(f"{bag}: topic {topic} cannot be read as {GRAPH_TOPICS[topic]}")
            for _, _, data in b.messages([name]):
                try:
                    out[topic].append((deserialize_message(data, cls), data))
                except Exception:
                    raise RetrackError(
                        f"{bag}: a message on {topic} does not deserialize"
                    ) from None
    return out


def _last_epoch(scenario, messages, bag) -> int:
    """The last epoch whose platform states and announced scans are all in the bag."""
    if not messages[topics.TRACKS]:
        raise RetrackError(f"{bag} holds no track arrays ({topics.TRACKS}): nothing to compare")
    sensors = {s.id for p in scenario.platforms for s in p.sensors}
    platforms = {p.id for p in scenario.platforms}
    bag_sensors = {m.sensor_id for m, _ in messages[topics.SCANS]}
    bag_platforms = {m.platform_id for m, _ in messages[topics.PLATFORM_STATES]}
    if bag_sensors - sensors or bag_platforms != platforms:
        raise RetrackError(
            f"the bag's sensors {sorted(bag_sensors)} and platforms {sorted(bag_platforms)} "
            f"are not scenario {scenario.name}'s ({sorted(sensors)}, {sorted(platforms)}): "
            "wrong --scenario?"
        )
    states: dict[int, list] = {}
    scans: dict[int, int] = {}
    for m, _ in messages[topics.PLATFORM_STATES]:
        states.setdefault(m.epoch, []).append(m)
    for m, _ in messages[topics.SCANS]:
        scans[m.epoch] = scans.get(m.epoch, 0) + 1
    last = 0
    for k in range(1, scenario.steps + 1):
        got = states.get(k, [])
        announced = max((m.epoch_measurement_count for m in got), default=0)
        if {m.platform_id for m in got} != platforms or scans.get(k, 0) < announced:
            break
        last = k
    if last == 0:
        raise RetrackError(f"{bag}: epoch 1 of scenario {scenario.name} is not in the bag")
    return last


class _Player(GraphNode):
    def __init__(self, raw: dict[int, list[tuple[str, bytes]]], key: GraphKey, **kwargs):
        super().__init__("retrack_player", graph_key=key, **kwargs)
        self.raw = raw
        self.pubs = {t: self.create_publisher(_CLASSES[t], t, writer_qos(t)) for t in _REPLAYED}

    def publish_epoch(self, k: int) -> None:
        for topic, data in self.raw.get(k, ()):
            msg = deserialize_message(data, _CLASSES[topic])
            self.pubs[topic].publish(self.graph_key.sign(serialize_message(msg)))


class _Collector(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("retrack_collector", **kwargs)
        self.arrays: dict[int, TrackArray] = {}
        self.subscribe(TrackArray, topics.TRACKS, lambda m: self.arrays.__setitem__(m.epoch, m))


def _same(a: TrackSet, b: TrackSet) -> tuple[bool, float]:
    """(identical, max |mean difference| over tracks of the same id; inf if the ids differ)."""
    if [t.track_id for t in a.tracks] != [t.track_id for t in b.tracks]:
        return False, float("inf")
    pairs = list(zip(a.tracks, b.tracks, strict=True))
    diff = max((float(np.abs(np.subtract(x.mean, y.mean)).max()) for x, y in pairs), default=0.0)
    same = all(
        x.status == y.status and np.array_equal(x.mean, y.mean) and np.array_equal(x.cov, y.cov)
        for x, y in pairs
    )
    return same, diff


def _mean_gospa(scenario, tracks: dict[int, TrackSet], truth: dict, epochs: int) -> float:
    ev = scenario.evaluation
    values = []
    for k in range(1, epochs + 1):
        X = np.asarray(truth[k].pv, dtype=float).reshape(-1, 4)[:, [0, 2]]
        Y = np.array([np.asarray(t.mean)[[0, 2]] for t in tracks[k].confirmed]).reshape(-1, 2)
        values.append(gospa(X, Y, ev.cutoff, ev.order, ev.alpha).distance)
    return float(np.mean(values))


def retrack_multi(
    bag,
    scenario_path: str,
    *,
    run: int | None = None,
    timeout: float = 300.0,
    stall_timeout: float = STALL_TIMEOUT,
) -> MultiRetrackReport:
    scenario = load_scenario(scenario_path)
    messages = _read(bag)
    last = _last_epoch(scenario, messages, bag)
    raw: dict[int, list[tuple[str, bytes]]] = {}
    for topic in _REPLAYED:
        for msg, data in messages[topic]:
            raw.setdefault(msg.epoch, []).append((topic, data))
    try:
        recorded = {m.epoch: track_array_from_msg(m, scenario) for m, _ in messages[topics.TRACKS]}
        truth = {
            m.epoch: truth_array_from_msg(m, scenario)
            for m, _ in messages[topics.GROUND_TRUTH_ARRAY]
        }
    except ValueError as exc:
        raise RetrackError(f"{bag}: {exc}: wrong --scenario?") from None
    params = [
        Parameter("scenario", value=str(scenario_path)),
        Parameter("run", value=-1 if run is None else run),
    ]
    key = GraphKey.generate()
    with InProcessGraph() as graph:
        quiet = {"context": graph.context, "start_parameter_services": False}
        collector = graph.add(_Collector(graph_key=key, **quiet))
        tracker = graph.add(MultiTrackerNode(parameter_overrides=params, graph_key=key, **quiet))
        player = graph.add(_Player(raw, key, **quiet))
        state = {"next": 1, "at": time.monotonic()}

        def replayed_all() -> bool:
            k, now = state["next"], time.monotonic()
            if k <= last and k - 1 in collector.arrays:
                player.publish_epoch(k)
                state.update(next=k + 1, at=now)
            trouble = _trouble(tracker.counters.counts)
            reached = max(collector.arrays, default=-1)
            if trouble:
                raise RetrackError(
                    f"the fresh tracker did not take the replay of epoch {reached + 1}: "
                    f"{trouble}: wrong --scenario or --run?"
                )
            if last not in collector.arrays and now - state["at"] > stall_timeout:
                raise RetrackError(f"the fresh tracker stopped at epoch {reached}")
            return last in collector.arrays

        if not graph.spin_until(replayed_all, timeout=timeout, step=0.0):
            raise RetrackError(f"retrack timed out after {timeout:g} s")
        replayed = {k: track_array_from_msg(m, scenario) for k, m in collector.arrays.items()}
    compared = [_same(recorded[k], replayed[k]) for k in range(last + 1) if k in recorded]
    scored = all(k in truth and k in recorded for k in range(1, last + 1))
    nan = float("nan")
    return MultiRetrackReport(
        epochs=last,
        identical=len(compared) == last + 1 and all(same for same, _ in compared),
        max_mean_difference=max(d for _, d in compared),
        recorded_gospa=_mean_gospa(scenario, recorded, truth, last) if scored else nan,
        replayed_gospa=_mean_gospa(scenario, replayed, truth, last) if scored else nan,
        warnings=[] if last == scenario.steps else [f"retracked epochs 1..{last} only"],
    )
