"""Validation inside the graph: a member with the key that sends bad data (a bug, a
misconfigured node) is stopped field by field, and no input whatsoever makes a callback raise.
"""

import math
import random
import time

import pytest
from adversary import CATEGORIES, Context, D, ForeignNode
from hypothesis import HealthCheck, given, settings
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from strategies import message

from activetrack.scenarios import load_scenario
from activetrack_bringup.evaluator import EvaluatorNode
from activetrack_bringup.runner import run_graph
from activetrack_ros.convert import header
from activetrack_ros.trust import GraphKey
from msgs_defs.msg import (
    BeamCommand,
    GroundTruthArray,
    ManoeuvreCommand,
    PlanReport,
    PlatformState,
    Scan,
    SensorSelection,
    TrackArray,
)
from planner_node.planner_node import PlannerNode
from sim_node.sim_node import SimNode
from tracker_node.tracker_node import TrackerNode

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros

# What each reader makes of each invalid category from a member of the graph: readers=counter,
# the counter that must rise by one per message ("rejected." implied unless another prefix is
# given), or "-": the reader accepts it (valid for what that reader needs).
VERDICT_TABLE = """
scan_nan                   tracker,evaluator=non_finite
scan_inf_position          tracker,evaluator=non_finite
scan_1e300                 tracker,evaluator=out_of_range
scan_bearing_4_rad         tracker,evaluator=out_of_range
scan_unknown_sensor        tracker,evaluator=unknown_sensor
scan_wrong_platform        tracker,evaluator=inconsistent
scan_negative_stamp        tracker,evaluator=bad_stamp
scan_bad_nanosec           tracker,evaluator=bad_stamp
scan_stamp_mismatch        tracker,evaluator=bad_stamp
scan_far_future            tracker,evaluator=future_epoch
scan_epoch_zero            tracker,evaluator=out_of_order
scan_old_epoch             tracker=out_of_order evaluator=-
scan_wrong_sigma           tracker,evaluator=sensor_mismatch
scan_nan_covariance        tracker,evaluator=non_finite
scan_wrong_kind            tracker,evaluator=wrong_sensor_kind
scan_polar_for_bearing_sensor tracker,evaluator=wrong_sensor_kind
scan_wrong_dim             tracker,evaluator=wrong_dimension
scan_too_many_detections   tracker,evaluator=wrong_dimension
scan_fov_not_the_sensors   tracker,evaluator=sensor_mismatch
scan_fov_nan               tracker,evaluator=out_of_range
scan_clutter_density       tracker,evaluator=sensor_mismatch
scan_count_exceeds_sensors tracker,evaluator=out_of_range
scan_huge_string           tracker,evaluator=unknown_sensor
state_unknown_platform     tracker,planner,evaluator=unknown_platform
state_nan_position         tracker,planner,evaluator=non_finite
state_1e300_velocity       tracker,planner,evaluator=out_of_range
state_negative_stamp       tracker,planner,evaluator=bad_stamp
state_far_future           tracker,planner,evaluator=future_epoch
state_other_sensors        tracker,planner,evaluator=sensor_mismatch
state_announces_more_than_sensors tracker,planner,evaluator=out_of_range
track_wrong_dimension      planner,evaluator=wrong_dimension sim=future_epoch
track_not_pd               planner,evaluator=bad_covariance sim=future_epoch
track_nan_state            planner,evaluator=non_finite sim=future_epoch
track_1e300_state          planner,evaluator=out_of_range sim=future_epoch
track_sample_mismatch      planner,evaluator=wrong_dimension sim=future_epoch
track_huge_sample_claim    planner,evaluator=wrong_dimension sim=future_epoch
track_bad_status           planner,evaluator=bad_field sim=future_epoch
track_unknown_origin       planner,evaluator=bad_field sim=future_epoch
track_duplicate_id         planner,evaluator=bad_field sim=future_epoch
track_more_unassociated    planner,evaluator=out_of_range sim=future_epoch
track_negative_stamp       planner,evaluator,sim=bad_stamp
track_future_epoch         planner,evaluator,sim=future_epoch
track_bad_filter_kind      planner,evaluator=bad_field sim=future_epoch
command_unknown_platform   sim=unknown_platform evaluator=bad_field
command_nan                sim,evaluator=non_finite
command_1e300_heading      sim,evaluator=out_of_range
command_1e300_speed        sim,evaluator=out_of_range
command_stale_epoch        sim=stale_epoch evaluator=-
command_future_epoch       sim=future_epoch evaluator=bad_field
command_negative_stamp     sim,evaluator=bad_stamp
beam_unknown_sensor        sim,evaluator=unknown_sensor
beam_not_steerable         sim,evaluator=unknown_sensor
beam_nan_bearing           sim,evaluator=unknown_sensor
selection_unknown_sensor   sim=unexpected_selection evaluator=unknown_sensor
report_nan_costs           evaluator=non_finite
report_length_mismatch     evaluator=wrong_dimension
truth_nan                  evaluator=non_finite
truth_unknown_target       evaluator=bad_field
truth_missing_state        evaluator=wrong_dimension
diagnostics_temperature    evaluator=ignored.other_diagnostics
diagnostics_many_statuses  evaluator=ignored.other_diagnostics
"""
VERDICTS = {
    line.split()[0]: {
        node: None if v == "-" else (v if "." in v else f"rejected.{v}")
        for nodes, v in (item.split("=") for item in line.split()[1:])
        for node in nodes.split(",")
    }
    for line in VERDICT_TABLE.strip().splitlines()
}

CALLBACKS = {  # node -> message type -> method name
    "sim": {
        ManoeuvreCommand: "on_command", BeamCommand: "on_beam", SensorSelection: "on_selection",
        TrackArray: "on_tracks",
    },
    "tracker": {Scan: "on_scan", PlatformState: "on_platform"},
    "planner": {TrackArray: "on_tracks", PlatformState: "on_platform"},
    "evaluator": {
        GroundTruthArray: "on_truth", TrackArray: "on_tracks", PlatformState: "on_platform",
        Scan: "on_scan", ManoeuvreCommand: "on_command", BeamCommand: "on_beam",
        SensorSelection: "on_selection", PlanReport: "on_report", D: "on_diagnostics",
    },
}  # fmt: skip


@pytest.fixture(scope="module")
def genuine(tmp_path_factory):
    """The graph's messages as of epoch 2 of a clean run (the templates of the categories)."""
    spies = []

    # With every category it stops listening only once it has seen each message a category
    # copies (the executor may hand it the track of epoch 2 before the truth).
    every = [c.name for c in CATEGORIES]

    def add(graph):
        spy = ForeignNode(dt=5.0, at_epoch=2, categories=every, context=graph.context)
        spies.append(graph.add(spy))

    run_graph(
        SCENARIO, run_dir=tmp_path_factory.mktemp("g"), record=False, plots=False, before_spin=add
    )
    spy = spies[0]
    return Context(2, 5.0, spy.latest, spy.seen, random.Random(0))


@pytest.fixture
def nodes(graph):
    """The graph's readers, unspun, as they are after epoch 2 (with a key: insiders' view)."""
    key = GraphKey.generate()
    params = [Parameter("scenario", value=SCENARIO)]
    kw = {"context": graph.context, "graph_key": key, "start_parameter_services": False}
    out = {
        "tracker": graph.add(TrackerNode(parameter_overrides=params, **kw)),
        "planner": graph.add(PlannerNode(parameter_overrides=params, **kw)),
        "sim": graph.add(SimNode(parameter_overrides=params, **kw)),
        "evaluator": graph.add(EvaluatorNode(load_scenario(SCENARIO), **kw)),
    }
    out["tracker"].last_epoch = 2
    out["planner"].last_decided = 1
    out["sim"].sim.epoch = 2
    return out


def test_every_invalid_category_has_a_verdict():
    invalid = {c.name for c in CATEGORIES if not c.plausible}
    assert invalid == set(VERDICTS)


@pytest.mark.parametrize("name", sorted(VERDICTS))
def test_an_insider_with_bad_data_is_rejected_for_the_right_reason(name, genuine, nodes):
    category = next(c for c in CATEGORIES if c.name == name)
    messages = category.build(genuine, category.msg_type)
    type_key = category.msg_type
    for node_name, verdict in VERDICTS[name].items():
        node = nodes[node_name]
        table = CALLBACKS[node_name]
        method = table[type_key]
        before = dict(node.counters.counts)
        for msg in messages:
            callback = getattr(node, method)
            if node_name == "evaluator" and type_key in RESULT_INPUTS:
                node.guarded(node._result_input, callback, msg)
            else:
                node.guarded(callback, msg)
        after = node.counters.counts
        changed = {k: v - before.get(k, 0) for k, v in after.items() if v != before.get(k, 0)}
        if verdict is None:
            assert not changed, f"{node_name} on {name}: {changed}"
        else:
            assert changed == {verdict: len(messages)}, f"{node_name} on {name}: {changed}"
    # A member's invalid result message (truth, track, state, report) is a graph fault: the
    # runner stops the run on it instead of waiting for an epoch that never validates.
    verdict = VERDICTS[name].get("evaluator")
    if verdict and verdict.startswith("rejected.") and type_key in RESULT_INPUTS:
        assert nodes["evaluator"].faults


def test_the_evaluator_takes_a_command_to_hold_course(nodes, genuine):
    """A planner that is off commands no change and gives no resulting heading or speed (NaN:
    not given): the evaluator takes it as the graph's own valid result, no fault."""
    evaluator = nodes["evaluator"]
    for raw in genuine.seen[PlatformState]:
        state = deserialize_message(raw, PlatformState)
        if state.epoch == 0:
            evaluator.guarded(evaluator._result_input, evaluator.on_platform, state)
    hold = ManoeuvreCommand(
        header=header(0.0), platform_id="p1", epoch=0, heading_change=0.0, speed_change=0.0,
        commanded_heading=math.nan, commanded_speed=math.nan,
    )  # fmt: skip
    before = dict(evaluator.counters.counts)
    evaluator.guarded(evaluator._result_input, evaluator.on_command, hold)
    assert evaluator.counters.counts == before and not evaluator.faults
    assert evaluator.commands[0]["p1"].heading_change == 0.0
    bad = ManoeuvreCommand(
        header=header(0.0), platform_id="p2", epoch=0, commanded_heading=math.inf
    )
    evaluator.guarded(evaluator._result_input, evaluator.on_command, bad)
    assert evaluator.counters.counts["rejected.non_finite"] == 1 and evaluator.faults


def test_an_incomplete_epoch_is_closed_after_the_timeout(graph, genuine):
    """Platform states announce two scans, one arrives: the tracker waits epoch_timeout, then
    updates with the one (counted) instead of stalling."""
    params = [Parameter("scenario", value=SCENARIO), Parameter("epoch_timeout", value=0.3)]
    tracker = graph.add(TrackerNode(context=graph.context, parameter_overrides=params))
    for raw in genuine.seen[PlatformState]:
        state = deserialize_message(raw, PlatformState)
        if state.epoch == 1:
            assert state.epoch_scan_count == 2
            tracker.guarded(tracker.on_platform, state)
    scans = [deserialize_message(raw, Scan) for raw in genuine.seen[Scan]]
    first = next(s for s in scans if s.epoch == 1)
    tracker.guarded(tracker.on_scan, first)
    assert tracker.last_epoch == 0 and len(tracker.epochs[1].scans) == 1
    start = time.monotonic()
    assert graph.spin_until(lambda: tracker.last_epoch == 1, timeout=5.0)
    assert 0.25 <= time.monotonic() - start < 2.0
    assert tracker.counters.counts["incomplete_epochs"] == 1
    assert tracker.counters.counts["updates"] == 1
    assert not tracker.epochs


# The evaluator's inputs that are results of the graph (all but /diagnostics): one of the
# graph's own that fails validation is a fault of the graph.
RESULT_INPUTS = tuple(t for t in CALLBACKS["evaluator"] if t is not D)
INPUTS = [(node, t) for node, table in CALLBACKS.items() for t in table]


@pytest.mark.parametrize(("node_name", "msg_type"), INPUTS, ids=lambda v: getattr(v, "__name__", v))
def test_no_input_makes_a_callback_raise(node_name, msg_type, graph):
    """Random messages (every field NaN, inf, huge, negative, odd lengths) into every callback
    of every node without a key (open mode, where nothing is filtered before validation): no
    exception escapes validation, i.e. nothing is counted as an error, and each message ends in
    exactly one of rejected / ignored / used."""
    params = [Parameter("scenario", value=SCENARIO)]
    kw = {"context": graph.context, "start_parameter_services": False}
    make = {
        "sim": lambda: SimNode(parameter_overrides=params, **kw),
        "tracker": lambda: TrackerNode(parameter_overrides=params, **kw),
        "planner": lambda: PlannerNode(parameter_overrides=params, **kw),
        "evaluator": lambda: EvaluatorNode(load_scenario(SCENARIO), **kw),
    }
    node = graph.add(make[node_name]())
    callback = getattr(node, CALLBACKS[node_name][msg_type])

    @settings(
        max_examples=120,
        derandomize=True,
        deadline=None,
        database=None,
        suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
    )
    @given(msg=message(msg_type))
    def check(msg):
        node.guarded(callback, msg)
        errors = {k: v for k, v in node.counters.counts.items() if k.startswith("errors.")}
        assert not errors, errors

    check()


def test_the_evaluator_gives_up_on_plan_reports_only_after_its_grace(graph, monkeypatch):
    """Missing plan reports (a dead planner) stop blocking completion report_grace_s after the
    sim and the tracker finished, and a last fetch from the writers' histories (here: none,
    ending at once): 1 s in one process, longer between processes (a participant that missed
    the planner's first discovery announcements hears the next one about 3 s later)."""
    from activetrack_bringup import refetch
    from activetrack_bringup.runner import REPORT_GRACE_PROCESSES_S

    monkeypatch.setattr(refetch, "REFETCH_S", 0.0)
    assert REPORT_GRACE_PROCESSES_S > 3.0
    sc = load_scenario(SCENARIO)
    kw = {"context": graph.context, "start_parameter_services": False}
    quick = graph.add(EvaluatorNode(sc, **kw))
    patient = graph.add(EvaluatorNode(sc, report_grace_s=REPORT_GRACE_PROCESSES_S, **kw))
    for node in (quick, patient):
        node._on_tick()
        assert node.expects_reports and not node._reports_given_up()  # sim not finished
        node.sim_finished_at = node.tracker_done_at = time.monotonic() - 2.0
        node._on_tick()  # quick: the last fetch starts
    assert quick.refetcher.busy() and not quick._reports_given_up()
    quick._on_tick()  # ... and ends (REFETCH_S 0), nothing found
    assert quick._reports_given_up() and not patient._reports_given_up()
    assert quick.counters.counts["refetch_unfilled.PlanReport"] == 1
    assert "plan report missing" in patient.missing() and "plan report" not in quick.missing()
    # the truth, states, scans and tracks are given up later (lost_grace: 5 s)
    assert quick.gave_up is None and "truth missing at epochs 0-" in quick.missing()
