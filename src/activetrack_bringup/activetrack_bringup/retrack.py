"""``activetrack bag retrack``: replay a recorded run's scans into a fresh tracker and compare
the tracks (README: Command line).

The replay is a player (the run's platform states and scans, re-signed with the replay's own
key, epoch k once the track array of k - 1 is out, as the lockstep simulator does) -> a fresh
``TrackerNode`` -> a collector of its track arrays. The bag is checked against the scenario
before anything spins, so a wrong ``--scenario`` fails at once with one line
(:class:`RetrackError`); while it spins, a tracker that rejects replayed messages, closes an
epoch incomplete or stops producing tracks ends the replay with the epoch it reached.
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass, field

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message, serialize_message

from activetrack.closed_loop.components import scene_targets
from activetrack.closed_loop.evaluation import EpochAssessor
from activetrack.data import TrackSet
from activetrack.filters import registry as filter_kinds
from activetrack.scenarios import load_scenario, with_tracker_overrides
from activetrack_bringup.bag import bag_topic, installed_type_hash
from activetrack_bringup.bag_io import BagError, open_bag
from activetrack_bringup.evaluator import held_estimates, truth_rows
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_ros import graph as topics
from activetrack_ros.convert import MessageError, TrackArrayChecker, truth_array_from_msg
from activetrack_ros.graph import GRAPH_TOPICS, writer_qos
from activetrack_ros.node_base import GraphNode, raise_interrupt_inside
from activetrack_ros.trust import GraphKey
from msgs_defs.msg import GroundTruthArray, PlatformState, TrackArray
from msgs_defs.msg import Scan as ScanMsg
from tracker_node.tracker_node import TrackerNode

REPLAYED_TOPICS = (topics.PLATFORM_STATES, topics.SCANS)  # in this order within an epoch
STAMP_TOLERANCE = 1e-6  # s between a stamp and its epoch time k T (the tracker's own check)
STALL_TIMEOUT = 10.0  # s without progress (a new track array) ends the replay
# Tracker counters that mean the replay is not the recorded run.
_TROUBLE = ("rejected.", "foreign.", "errors.", "dropped.", "incomplete_epochs")
# Topics of bags recorded before every measurement travelled as a Scan (activetrack 0.1).
_FORMER_MEASUREMENT_TOPICS = (
    "activetrack/bearing_measurements",
    "activetrack/polar_measurements",
    "activetrack/measurements",
)

_CLASSES = {
    topics.PLATFORM_STATES: PlatformState,
    topics.SCANS: ScanMsg,
    topics.TRACKS: TrackArray,
    topics.GROUND_TRUTH: GroundTruthArray,
}


class RetrackError(BagError):
    """The bag cannot be retracked with this scenario (one line, says why)."""


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


def read_run(bag, use: str = "retrack", skip_damaged: bool = False) -> RunData:
    """The run's scans, platform states, track arrays and truth; RetrackError when the bag has
    lost data, is cut off (a killed recorder) unless ``skip_damaged`` (its epochs up to the
    cut are read), or a needed topic is unreadable or of another type (version). ``use``: the
    command, for the messages."""
    with open_bag(bag) as b:
        lost = b.lost
        if lost:
            raise RetrackError(
                f"{lost[0]} ({len(lost)} problem(s) with lost data): {use} needs every scan "
                "of the run"
            )
        cut = b.cut
        if cut and not skip_damaged:
            raise RetrackError(
                f"{cut[0]} (the recording was cut off: its last messages are missing): "
                f"`--skip-damaged` {use}s the epochs it holds, `activetrack bag recover "
                f"{bag}` rewrites the bag"
            )
        former = [t for t in _FORMER_MEASUREMENT_TOPICS if bag_topic(b, t)]
        if former and not bag_topic(b, topics.SCANS):
            raise RetrackError(
                f"{bag} was recorded by activetrack 0.1 (measurements on {former[0]}, no "
                f"{topics.SCANS}): this version replays scans only; retrack it with 0.1"
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
                    f"{bag}: topic {topic} holds {t.msgtype}, not {GRAPH_TOPICS[topic]} "
                    "(recorded by another version of activetrack)"
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
                except Exception as exc:
                    raise_interrupt_inside(exc)
                    raise RetrackError(
                        f"{bag}: a {t.msgtype} message on {topic} (log time {log_time}) does "
                        "not deserialize"
                    ) from None
                msgs.append(msg)
                if topic in REPLAYED_TOPICS:
                    run.raw.setdefault(msg.epoch, []).append((topic, data))
        _read_diagnostics(b, run)
    for batch in run.raw.values():  # platform states first, then scans (stable)
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
        except Exception as exc:
            raise_interrupt_inside(exc)
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
    scans = run.messages[topics.SCANS]
    tracks = run.messages[topics.TRACKS]
    used = run.scenario_name
    hint = f" (the run used scenario {used!r})" if used and used != scenario.name else ""
    if not scans:
        raise RetrackError(f"{bag} holds no scans ({topics.SCANS}): nothing to retrack")
    if not tracks:
        raise RetrackError(f"{bag} holds no track arrays ({topics.TRACKS}): nothing to compare")
    _check_sensors(scenario, run, scans, hint)
    _check_tracks(scenario, tracks[0], hint)
    top = _check_timing(scenario, run, scans, hint)
    return _last_replayable(scenario, run, scans, top, hint, bag)


def _check_sensors(scenario, run: RunData, scans: list, hint: str) -> None:
    """The bag's sensors, their kinds and platforms are the scenario's."""
    name = scenario.name
    states = run.messages[topics.PLATFORM_STATES]
    kinds = {s.id: s.kind for p in scenario.platforms for s in p.sensors}
    owner = {s.id: p.id for p in scenario.platforms for s in p.sensors}
    platforms = {p.id for p in scenario.platforms}
    sensors = {m.sensor_id for m in scans}
    if sensors - kinds.keys():
        raise RetrackError(
            f"the bag's scans come from sensors {sorted(sensors - kinds.keys())} that "
            f"scenario {name} does not have (it has {sorted(kinds)}): wrong --scenario?{hint}"
        )
    for m in scans:
        if m.sensor_kind != kinds[m.sensor_id]:
            raise RetrackError(
                f"sensor {m.sensor_id!r} is a {m.sensor_kind} sensor in the bag but a "
                f"{kinds[m.sensor_id]} sensor in scenario {name}: wrong --scenario?{hint}"
            )
        if owner[m.sensor_id] != m.platform_id:
            raise RetrackError(
                f"sensor {m.sensor_id!r} is on platform {m.platform_id!r} in the bag, on "
                f"{owner[m.sensor_id]!r} in scenario {name}: wrong --scenario?{hint}"
            )
    seen = {m.platform_id for m in scans} | {s.platform_id for s in states}
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


def _check_tracks(scenario, array, hint: str) -> None:
    """The recorded tracks have the scenario's motion model and state."""
    checker = TrackArrayChecker(scenario)
    if array.motion_model != checker.motion_model or tuple(array.state_names) != (
        checker.state_names
    ):
        raise RetrackError(
            f"the recorded tracks' state is {array.motion_model} ({', '.join(array.state_names)}); "
            f"scenario {scenario.name}'s is {checker.motion_model} "
            f"({', '.join(checker.state_names)}): wrong --scenario?{hint}"
        )
    targets = {t.id for t in scene_targets(scenario)}
    origins = {t.origin for t in array.tracks if t.origin}
    if origins - targets:
        raise RetrackError(
            f"the recorded tracks are of targets {sorted(origins)}, scenario {scenario.name} "
            f"has {sorted(targets)}: wrong --scenario?{hint}"
        )


def _check_timing(scenario, run: RunData, scans: list, hint: str) -> int:
    """Steps, epochs and stamps fit the scenario's; returns the bag's last epoch."""
    name, steps, dt = scenario.name, scenario.steps, scenario.dt
    states = run.messages[topics.PLATFORM_STATES]
    tracks = run.messages[topics.TRACKS]
    if run.steps is not None and run.steps != steps:
        raise RetrackError(
            f"the recorded run has {run.steps} steps (its simulator's diagnostics), scenario "
            f"{name} has {steps}: wrong --scenario?{hint}"
        )
    top = max(m.epoch for group in (scans, states, tracks) for m in group)
    if top > steps:
        raise RetrackError(
            f"the bag holds epoch {top}, scenario {name} has {steps} steps: wrong --scenario?{hint}"
        )
    for m in (*scans, *states):
        if abs(_stamp(m) - m.epoch * dt) > STAMP_TOLERANCE:
            implied = f"dt = {_stamp(m) / m.epoch:g} s" if m.epoch else "another time origin"
            raise RetrackError(
                f"the bag's stamps imply {implied} (epoch {m.epoch} at {_stamp(m):g} s), "
                f"scenario {name} has dt = {dt:g} s: wrong --scenario?{hint}"
            )
    return top


def _last_replayable(scenario, run: RunData, scans: list, top: int, hint: str, bag) -> int:
    """The last epoch with all platforms' states and the announced scans; a warning in
    ``run.warnings`` when that is not the scenario's last."""
    name, steps = scenario.name, scenario.steps
    platforms = {p.id for p in scenario.platforms}
    per_epoch: dict[int, list] = {}
    for s in run.messages[topics.PLATFORM_STATES]:
        per_epoch.setdefault(s.epoch, []).append(s)
    counts: dict[int, int] = {}
    for m in scans:
        counts[m.epoch] = counts.get(m.epoch, 0) + 1
    last = 0
    for k in range(1, steps + 1):
        got = per_epoch.get(k, [])
        announced = max((s.epoch_scan_count for s in got), default=0)
        if {s.platform_id for s in got} != platforms or counts.get(k, 0) < announced:
            break
        last = k
    if last < top - 1 or last == 0:
        k = last + 1
        got = {s.platform_id for s in per_epoch.get(k, [])}
        lacks = (
            f"the platform states of {sorted(platforms - got)}"
            if got != platforms
            else f"scans ({counts.get(k, 0)} recorded, "
            f"{max(s.epoch_scan_count for s in per_epoch[k])} announced)"
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


class _EpochPlayer(GraphNode):
    """Publishes the recorded messages of one epoch at a time (graph QoS, like the simulator),
    signed with the replay's own key: the recording run's key is gone, and a writer elsewhere
    on the domain must not be able to feed the fresh tracker."""

    def __init__(self, raw: dict[int, list], key: GraphKey, **kwargs):
        super().__init__("retrack_player", graph_key=key, **kwargs)
        self.raw = raw
        self.pubs = {
            t: self.create_publisher(_CLASSES[t], t, writer_qos(t)) for t in REPLAYED_TOPICS
        }

    def publish_epoch(self, k: int) -> None:
        for topic, data in self.raw.get(k, ()):
            msg = deserialize_message(data, _CLASSES[topic])  # re-serialised: drops padding
            self.pubs[topic].publish(self.graph_key.sign(serialize_message(msg)))


class _TrackCollector(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("retrack_collector", **kwargs)
        self.arrays: dict[int, TrackArray] = {}
        self.subscribe(TrackArray, topics.TRACKS, lambda m: self.arrays.__setitem__(m.epoch, m))


@dataclass
class RetrackReport:
    """``identical``: every replayed track array equals the recorded one (ids, status, states,
    covariances); the largest state and covariance differences over tracks of the same id
    (inf: the track sets differ); each target's time-averaged RMSE in x and y and the
    time-averaged GOSPA of both against the recorded truth (NaN without truth)."""

    epochs: int
    recorded_filter: str
    replayed_filter: str
    identical: bool
    max_state_difference: float
    max_covariance_difference: float
    target_ids: tuple[str, ...]
    recorded_time_avg_rmse: list[tuple[float, float]]
    replayed_time_avg_rmse: list[tuple[float, float]]
    recorded_gospa: float
    replayed_gospa: float
    warnings: list[str] = field(default_factory=list)

    def to_json(self) -> dict:
        return dict(self.__dict__)


def _differences(a: TrackSet, b: TrackSet) -> tuple[bool, float, float]:
    """(identical, max |state difference|, max |covariance difference|) over tracks of the
    same id; inf when the ids differ."""
    if [t.track_id for t in a.tracks] != [t.track_id for t in b.tracks]:
        return False, math.inf, math.inf
    pairs = list(zip(a.tracks, b.tracks, strict=True))
    ds = max((float(np.abs(x.state - y.state).max()) for x, y in pairs), default=0.0)
    dc = max((float(np.abs(x.state_cov - y.state_cov).max()) for x, y in pairs), default=0.0)
    same = all(
        x.status == y.status
        and np.array_equal(x.state, y.state)
        and np.array_equal(x.state_cov, y.state_cov)
        for x, y in pairs
    )
    return same, ds, dc


def _scores(scenario, tracks: dict[int, TrackSet], truth: dict, epochs: int):
    """Each target's time-averaged RMSE (x, y) and the time-averaged GOSPA over 1..epochs."""
    assess = EpochAssessor(scenario)
    index = {t.id: n for n, t in enumerate(scene_targets(scenario))}
    errors, gospas = [], []
    for k in range(1, epochs + 1):
        pv = truth_rows(truth[k], index)
        a = assess(pv, tracks[k], k)
        errors.append(np.abs(held_estimates(a, tracks[k], pv) - pv)[:, [0, 2]])
        gospas.append(a.gospa)
    with np.errstate(invalid="ignore"):
        rmse = np.nanmean(np.array(errors), axis=0)  # one run: the mean absolute error
    return [(float(x), float(y)) for x, y in rmse], float(np.mean(gospas))


def retrack(
    bag,
    scenario_path: str,
    *,
    filter_kind: str | None = None,
    run: int | None = None,
    timeout: float = 300.0,
    stall_timeout: float = STALL_TIMEOUT,
    skip_damaged: bool = False,
) -> RetrackReport:
    scenario = load_scenario(scenario_path)  # imports the scenario's plugins (filters too)
    if filter_kind is not None:
        try:
            filter_kinds.filter_kind(filter_kind)
        except ValueError as exc:
            raise RetrackError(f"--filter: {exc}") from None
    data = read_run(bag, skip_damaged=skip_damaged)
    last = check_run(scenario, data, bag)
    check = TrackArrayChecker(scenario)
    try:
        recorded = {m.epoch: check(m) for m in data.messages[topics.TRACKS]}
        truth = {
            m.epoch: truth_array_from_msg(m, scenario) for m in data.messages[topics.GROUND_TRUTH]
        }
    except MessageError as exc:
        raise RetrackError(f"{bag}: {exc}: wrong --scenario?") from None
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
            if k <= last and k - 1 in collector.arrays:
                player.publish_epoch(k)  # lockstep: epoch k once the tracks of k - 1 are out
                state.update(next=k + 1, at=now)
            reached = max(collector.arrays, default=-1)
            trouble = {
                k: v for k, v in tracker.counters.counts.items() if v and k.startswith(_TROUBLE)
            }
            if trouble:
                raise RetrackError(
                    f"the fresh tracker did not take the replay of epoch {reached + 1}: "
                    f"{trouble} (see its log above): wrong --scenario or --run?"
                )
            if last not in collector.arrays and now - state["at"] > stall_timeout:
                raise RetrackError(
                    f"the fresh tracker stopped at epoch {reached}: no tracks for epoch "
                    f"{reached + 1} within {stall_timeout:g} s of its messages"
                )
            return last in collector.arrays

        if not graph.spin_until(replayed_all, timeout=timeout, step=0.0):
            raise RetrackError(
                f"retrack timed out after {timeout:g} s at epoch "
                f"{max(collector.arrays, default=0)} of {last}"
            )
        # The replayed arrays are of the fresh tracker's filter (``filter_kind``, if given).
        check_replayed = TrackArrayChecker(with_tracker_overrides(scenario, filter=filter_kind))
        replayed = {k: check_replayed(m) for k, m in collector.arrays.items()}
    common = [k for k in range(last + 1) if k in recorded and k in replayed]
    compared = [_differences(recorded[k], replayed[k]) for k in common]
    scored = all(k in truth and k in recorded for k in range(1, last + 1))
    unscored = ([(math.nan, math.nan)] * len(scene_targets(scenario)), math.nan)
    (rec_rmse, rec_gospa), (rep_rmse, rep_gospa) = (
        _scores(scenario, t, truth, last) if scored else unscored for t in (recorded, replayed)
    )
    return RetrackReport(
        epochs=len(common) - 1,
        recorded_filter=recorded[common[0]].filter_kind,
        replayed_filter=replayed[common[0]].filter_kind,
        identical=len(common) == last + 1 and all(same for same, _, _ in compared),
        max_state_difference=max(ds for _, ds, _ in compared),
        max_covariance_difference=max(dc for _, _, dc in compared),
        target_ids=tuple(t.id for t in scene_targets(scenario)),
        recorded_time_avg_rmse=rec_rmse,
        replayed_time_avg_rmse=rep_rmse,
        recorded_gospa=rec_gospa,
        replayed_gospa=rep_gospa,
        warnings=data.warnings,
    )
