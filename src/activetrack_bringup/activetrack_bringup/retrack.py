"""Replay a recorded run's measurements into a fresh tracker and compare the tracks.

With the recorded configuration the replayed track equals the recorded one exactly (the
tracker is deterministic for a seed); with another filter (``--filter``) the report compares
both against the recorded ground truth.

The replay is a player (the run's platform states and measurements, their recorded bytes
unchanged, epoch by epoch: epoch k once the track of k - 1 is out, as the simulator does in
lockstep) -> a fresh ``TrackerNode`` -> a collector of its tracks. Before anything spins, the
bag is checked against the scenario (sensor and platform ids, the recorded track's state, the
epochs and steps, dt against the message stamps), so a wrong ``--scenario`` fails at once with
one line (:class:`RetrackError`); while it spins, the wait is bounded: a tracker that rejects
or drops replayed messages, closes an epoch incomplete or stops producing tracks ends the
replay with the epoch it reached.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message

from activetrack.filters import registry as filter_kinds
from activetrack.scenarios import load_scenario
from activetrack.scenarios.build import build_motion_model
from activetrack_bringup.bag import bag_topic, installed_type_hash
from activetrack_bringup.bag_io import BagError, open_bag
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_ros import graph as topics
from activetrack_ros.convert import measurement_topic
from activetrack_ros.graph import GRAPH_TOPICS, writer_qos
from activetrack_ros.node_base import GraphNode
from activetrack_ros.trust import GraphKey, is_signed_type
from msgs_defs.msg import (
    BearingMeasurement,
    GroundTruth,
    Measurement,
    PlatformState,
    PolarMeasurement,
    TrackEstimate,
)
from tracker_node.tracker_node import TrackerNode

MEASUREMENT_TOPICS = (topics.BEARING_MEASUREMENTS, topics.POLAR_MEASUREMENTS, topics.MEASUREMENTS)
REPLAYED_TOPICS = (*MEASUREMENT_TOPICS, topics.PLATFORM_STATES)
STAMP_TOLERANCE = 1e-6  # s between a stamp and its epoch time k T (the tracker's own check)
STALL_TIMEOUT = 10.0  # s without progress (a new track or a replayed message) ends the replay
# Tracker counters that mean the replay is not the recorded run.
_TROUBLE = ("rejected.", "foreign.", "errors.", "dropped.", "incomplete_epochs")

_CLASSES = {
    topics.BEARING_MEASUREMENTS: BearingMeasurement,
    topics.POLAR_MEASUREMENTS: PolarMeasurement,
    topics.MEASUREMENTS: Measurement,
    topics.PLATFORM_STATES: PlatformState,
    topics.TRACK: TrackEstimate,
    topics.GROUND_TRUTH: GroundTruth,
}


class RetrackError(BagError):
    """The bag cannot be retracked with this scenario (one line, says why)."""


def read_topic(bag, topic: str, msg_type) -> list:
    """Deserialize every message of one topic of a bag (rclpy, exact); ``topic`` as the bag
    names it or a graph topic under any namespace."""
    with open_bag(bag) as b:
        name = bag_topic(b, topic)
        if name is None:
            return []
        return [deserialize_message(d, msg_type) for _, _, d in b.messages([name])]


@dataclass
class RunData:
    """What retrack reads from a bag (deserialized), and whether the recording was complete."""

    messages: dict[str, list] = field(default_factory=dict)
    raw: dict[int, list] = field(default_factory=dict)  # epoch -> [(topic, bytes)] to replay
    finished: bool = True  # the recording was closed (not killed)
    sim_finished: bool = False  # the simulator said it ran the scenario to its end
    steps: int | None = None  # the run's steps, from the simulator's "epoch k/K" diagnostics
    scenario_name: str | None = None  # the scenario the run's nodes named in their diagnostics
    warnings: list[str] = field(default_factory=list)


def read_run(bag) -> RunData:
    """The run's measurements, platform states, tracks and truth; RetrackError when the bag
    has lost data, or a needed topic is unreadable or of another type (version)."""
    with open_bag(bag) as b:
        lost = b.lost
        if lost:
            raise RetrackError(
                f"{lost[0]} ({len(lost)} problem(s) with lost data): retrack needs every "
                "measurement of the run"
            )
        run = RunData(finished=all(s.finished for s in b.scans))
        run.warnings = [str(d) for d in b.damage]
        for topic, cls in _CLASSES.items():
            name = bag_topic(b, topic)
            t = b.topics.get(name) if name else None
            run.messages[topic] = []
            if t is None or not t.count:
                continue
            if t.problem:
                raise RetrackError(f"{bag}: topic {topic} cannot be read: {t.problem}")
            if t.msgtype != GRAPH_TOPICS[topic]:
                raise RetrackError(
                    f"{bag}: topic {topic} holds {t.msgtype}, not {GRAPH_TOPICS[topic]}"
                )
            installed = installed_type_hash(t.msgtype)
            if t.rihs01 and installed and t.rihs01 != installed:
                raise RetrackError(
                    f"{bag}: its {t.msgtype} is not the installed definition (recorded with "
                    "another version of msgs_defs): the tracker cannot read it"
                )
            msgs = run.messages[topic]
            for _, log_time, data in b.messages([name]):
                try:
                    msg = deserialize_message(data, cls)
                except Exception:
                    raise RetrackError(
                        f"{bag}: a {t.msgtype} message on {topic} (log time {log_time}) does "
                        "not deserialize"
                    ) from None
                msgs.append(msg)
                if topic in REPLAYED_TOPICS:
                    run.raw.setdefault(msg.epoch, []).append((topic, data))
        _read_diagnostics(b, run)
    for batch in run.raw.values():  # platform states first, then measurements (stable)
        batch.sort(key=lambda m: m[0] != topics.PLATFORM_STATES)
    return run


def _read_diagnostics(b, run: RunData) -> None:
    """Whether the simulator finished, and the scenario name the nodes reported (optional)."""
    name = bag_topic(b, topics.DIAGNOSTICS)
    t = b.topics.get(name) if name else None
    if t is None or t.problem or t.msgtype != GRAPH_TOPICS[topics.DIAGNOSTICS]:
        return
    for _, _, data in b.messages([name]):
        try:
            array = deserialize_message(data, DiagnosticArray)
        except Exception:
            continue
        for status in array.status:
            if status.name.endswith("sim_node"):
                run.scenario_name = status.hardware_id or run.scenario_name
                run.sim_finished = run.sim_finished or status.message == "finished"
                progress = re.fullmatch(r"epoch (\d+)/(\d+)", status.message)
                if progress:
                    run.steps = int(progress[2])
                    run.sim_finished = run.sim_finished or progress[1] == progress[2]


def _stamp(msg) -> float:
    return msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9


def check_run(scenario, run: RunData, bag) -> int:
    """Check the bag against the scenario; return the last epoch to replay. RetrackError (one
    line) at the first mismatch."""
    meas = [m for t in MEASUREMENT_TOPICS for m in run.messages[t]]
    tracks = run.messages[topics.TRACK]
    used = run.scenario_name
    hint = f" (the run used scenario {used!r})" if used and used != scenario.name else ""
    if not meas:
        raise RetrackError(
            f"{bag} holds no measurements ({', '.join(MEASUREMENT_TOPICS)}): nothing to retrack"
        )
    if not tracks:
        raise RetrackError(f"{bag} holds no recorded track ({topics.TRACK}): nothing to compare")
    _check_sensors(scenario, run, meas, hint)
    _check_track(scenario, tracks[0], hint)
    top = _check_timing(scenario, run, meas, hint)
    return _last_replayable(scenario, run, meas, top, hint, bag)


def _check_sensors(scenario, run: RunData, meas: list, hint: str) -> None:
    """The bag's sensors, their kinds and platforms are the scenario's."""
    name = scenario.name
    states = run.messages[topics.PLATFORM_STATES]
    kinds = {s.id: s.kind for p in scenario.platforms for s in p.sensors}
    owner = {s.id: p.id for p in scenario.platforms for s in p.sensors}
    platforms = {p.id for p in scenario.platforms}
    sensors = {m.sensor_id for m in meas}
    if sensors - kinds.keys():
        raise RetrackError(
            f"the bag's measurements come from sensors {sorted(sensors - kinds.keys())} that "
            f"scenario {name} does not have (it has {sorted(kinds)}): wrong --scenario?{hint}"
        )
    for topic in MEASUREMENT_TOPICS:
        for m in run.messages[topic]:
            if measurement_topic(kinds[m.sensor_id]) != topic:
                raise RetrackError(
                    f"sensor {m.sensor_id!r} measures on {topic} in the bag but is a "
                    f"{kinds[m.sensor_id]} sensor in scenario {name}: wrong --scenario?{hint}"
                )
    seen = {m.platform_id for m in meas} | {s.platform_id for s in states}
    if seen - platforms:
        raise RetrackError(
            f"the bag holds platforms {sorted(seen - platforms)} that scenario {name} does not "
            f"have (it has {sorted(platforms)}): wrong --scenario?{hint}"
        )
    unseen = platforms - {s.platform_id for s in states}
    if states and unseen:
        raise RetrackError(
            f"scenario {name} has platforms {sorted(unseen)} that the bag's run does not have "
            f"(it has {sorted(platforms - unseen)}): wrong --scenario?{hint}"
        )
    for m in meas:
        if owner[m.sensor_id] != m.platform_id:
            raise RetrackError(
                f"sensor {m.sensor_id!r} is on platform {m.platform_id!r} in the bag, on "
                f"{owner[m.sensor_id]!r} in scenario {name}: wrong --scenario?{hint}"
            )


def _check_track(scenario, track, hint: str) -> None:
    """The recorded track has the scenario's state and target."""
    name = scenario.name
    motion = scenario.tracker.motion or scenario.target.motion
    names = tuple(build_motion_model(motion).state_names)
    if tuple(track.state_names) != names or len(track.state) != len(names):
        raise RetrackError(
            f"the recorded track's state is ({', '.join(track.state_names)}), "
            f"{len(track.state)} values; scenario {name}'s {motion.model} model has "
            f"({', '.join(names)}): wrong --scenario?{hint}"
        )
    if track.target_id != scenario.target.id:
        raise RetrackError(
            f"the recorded track is of target {track.target_id!r}, scenario {name} tracks "
            f"{scenario.target.id!r}: wrong --scenario?{hint}"
        )


def _check_timing(scenario, run: RunData, meas: list, hint: str) -> int:
    """Steps, epochs and stamps fit the scenario's; returns the bag's last epoch."""
    name, steps, dt = scenario.name, scenario.steps, scenario.dt
    states = run.messages[topics.PLATFORM_STATES]
    tracks = run.messages[topics.TRACK]
    if run.steps is not None and run.steps != steps:
        raise RetrackError(
            f"the recorded run has {run.steps} steps (its simulator's diagnostics), scenario "
            f"{name} has {steps}: wrong --scenario?{hint}"
        )
    top = max(m.epoch for group in (meas, states, tracks) for m in group)
    if top > steps:
        raise RetrackError(
            f"the bag holds epoch {top}, scenario {name} has {steps} steps: wrong --scenario?{hint}"
        )
    for m in (*meas, *states):
        if abs(_stamp(m) - m.epoch * dt) > STAMP_TOLERANCE:
            implied = f"dt = {_stamp(m) / m.epoch:g} s" if m.epoch else "another time origin"
            raise RetrackError(
                f"the bag's stamps imply {implied} (epoch {m.epoch} at {_stamp(m):g} s), "
                f"scenario {name} has dt = {dt:g} s: wrong --scenario?{hint}"
            )
    return top


def _last_replayable(scenario, run: RunData, meas: list, top: int, hint: str, bag) -> int:
    """The last epoch with all platforms' states and the announced measurements; a warning in
    ``run.warnings`` when that is not the scenario's last."""
    name, steps = scenario.name, scenario.steps
    platforms = {p.id for p in scenario.platforms}
    per_epoch: dict[int, list] = {}
    for s in run.messages[topics.PLATFORM_STATES]:
        per_epoch.setdefault(s.epoch, []).append(s)
    counts: dict[int, int] = {}
    for m in meas:
        counts[m.epoch] = counts.get(m.epoch, 0) + 1
    last = 0
    for k in range(1, steps + 1):
        got = per_epoch.get(k, [])
        announced = max((s.epoch_measurement_count for s in got), default=0)
        if {s.platform_id for s in got} != platforms or counts.get(k, 0) < announced:
            break
        last = k
    if last < top - 1 or last == 0:
        k = last + 1
        got = {s.platform_id for s in per_epoch.get(k, [])}
        lacks = (
            f"the platform states of {sorted(platforms - got)}"
            if got != platforms
            else f"measurements ({counts.get(k, 0)} recorded, "
            f"{max(s.epoch_measurement_count for s in per_epoch[k])} announced)"
        )
        raise RetrackError(
            f"the bag's run cannot be replayed past epoch {last} of scenario {name}'s {steps}: "
            f"epoch {k} lacks {lacks}{hint}"
        )
    if last < steps and run.sim_finished:
        raise RetrackError(
            f"the recorded run finished at epoch {last}, scenario {name} has {steps} steps: "
            f"wrong --scenario?{hint}"
        )
    if last < steps:
        why = "the recording did not finish" if not run.finished else "the run was interrupted"
        run.warnings.append(f"{bag}: {why}; retracking epochs 1..{last} of {steps}")
    return last


class _EpochPlayer(Node):
    """Publishes the recorded messages of one epoch at a time (graph QoS, like the simulator),
    signed with the replay's own key: the recording run's key is gone, and a writer elsewhere
    on the domain must not be able to feed the fresh tracker."""

    def __init__(self, raw: dict[int, list], key: GraphKey, **kwargs):
        super().__init__("retrack_player", **kwargs)
        self.raw = raw
        self.key = key
        self.pubs = {
            t: self.create_publisher(_CLASSES[t], t, writer_qos(t))
            for t in {t for batch in raw.values() for t, _ in batch}
        }
        self.published = 0

    def publish_epoch(self, k: int) -> None:
        for topic, data in self.raw.get(k, ()):
            cls = _CLASSES[topic]
            if is_signed_type(cls):  # re-serialised: drops any transport padding first
                data = self.key.sign(serialize_message(deserialize_message(data, cls)))
            self.pubs[topic].publish(data)
            self.published += 1


class _TrackCollector(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("retrack_collector", **kwargs)
        self.tracks: dict[int, TrackEstimate] = {}
        self.subscribe(TrackEstimate, topics.TRACK, lambda m: self.tracks.__setitem__(m.epoch, m))


@dataclass
class RetrackReport:
    epochs: int
    recorded_filter: str
    replayed_filter: str
    max_state_difference: float
    max_covariance_difference: float
    recorded_rmse: tuple[float, float]
    replayed_rmse: tuple[float, float]
    warnings: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        return dict(self.__dict__)


def _rmse(tracks: dict, truth: dict) -> tuple[float, float]:
    """RMSE in x and y over the epochs k >= 1 (position entries named x/y or px/py)."""
    ks = sorted(k for k in tracks if k in truth and k > 0)
    if not ks:
        return (math.nan, math.nan)
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


def _trouble(counters) -> dict:
    return {k: v for k, v in counters.items() if v and k.startswith(_TROUBLE)}


def retrack(
    bag,
    scenario_path: str,
    *,
    filter_kind: str | None = None,
    run: int | None = None,
    timeout: float = 300.0,
    stall_timeout: float = STALL_TIMEOUT,
) -> RetrackReport:
    scenario = load_scenario(scenario_path)  # imports the scenario's plugins (filters too)
    if filter_kind is not None:
        try:
            filter_kinds.filter_kind(filter_kind)
        except ValueError as exc:
            raise RetrackError(f"--filter: {exc}") from None
    data = read_run(bag)
    last = check_run(scenario, data, bag)
    recorded = {m.epoch: m for m in data.messages[topics.TRACK]}
    truth = {m.epoch: m for m in data.messages[topics.GROUND_TRUTH]}
    params = [
        Parameter("scenario", value=str(scenario_path)),
        Parameter("run", value=-1 if run is None else run),
        Parameter("filter", value=filter_kind or ""),
    ]
    key = GraphKey.generate()
    with InProcessGraph() as graph:
        quiet = {"context": graph.context, "start_parameter_services": False}
        collector = graph.add(_TrackCollector(graph_key=key, **quiet))
        tracker = graph.add(TrackerNode(parameter_overrides=params, graph_key=key, **quiet))
        player = graph.add(_EpochPlayer(data.raw, key, **quiet))
        state = {"next": 1, "at": time.monotonic()}

        def replayed_all() -> bool:
            k = state["next"]
            now = time.monotonic()
            if k <= last and k - 1 in collector.tracks:
                player.publish_epoch(k)  # lockstep: epoch k once the track of k - 1 is out
                state.update(next=k + 1, at=now)
            reached = max(collector.tracks, default=-1)
            trouble = _trouble(tracker.counters.counts)
            if trouble:
                raise RetrackError(
                    f"the fresh tracker did not take the replay of epoch {reached + 1}: "
                    f"{trouble} (see its log above): wrong --scenario or --run?"
                )
            if last not in collector.tracks and now - state["at"] > stall_timeout:
                raise RetrackError(
                    f"the fresh tracker stopped at epoch {reached}: no track for epoch "
                    f"{reached + 1} within {stall_timeout:g} s of its messages"
                )
            return last in collector.tracks

        if not graph.spin_until(replayed_all, timeout=timeout, step=0.0):
            raise RetrackError(
                f"retrack timed out after {timeout:g} s at epoch "
                f"{max(collector.tracks, default=0)} of {last}"
            )
        replayed = dict(collector.tracks)
        warnings = data.warnings
    common = sorted(k for k in set(recorded) & set(replayed) if k <= last)
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
        recorded_rmse=_rmse({k: recorded[k] for k in common}, truth),
        replayed_rmse=_rmse({k: replayed[k] for k in common}, truth),
        warnings=warnings,
    )


def measurement_topics_in(bag) -> list[str]:
    """The measurement topics a bag holds."""
    with open_bag(bag) as b:
        return [t for t in MEASUREMENT_TOPICS if t in b.topics and b.topics[t].count]
