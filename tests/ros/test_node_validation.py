"""Validation inside the graph: a member with the key that sends bad data (a bug, a
misconfigured node) is stopped field by field, and no input whatsoever makes a callback raise.
"""

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
from activetrack_ros.trust import GraphKey
from msgs_defs.msg import (
    BearingMeasurement,
    GroundTruth,
    ManoeuvreCommand,
    Measurement,
    PlanReport,
    PlatformState,
    PolarMeasurement,
    SensorSelection,
    TrackEstimate,
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
bearing_nan                tracker=non_finite evaluator=-
bearing_inf_position       tracker=non_finite evaluator=-
bearing_1e300              tracker=out_of_range evaluator=-
bearing_unknown_sensor     tracker=unknown_sensor evaluator=bad_field
bearing_wrong_platform     tracker=inconsistent evaluator=-
bearing_negative_stamp     tracker=bad_stamp evaluator=-
bearing_bad_nanosec        tracker=bad_stamp evaluator=-
bearing_stamp_mismatch     tracker=bad_stamp evaluator=-
bearing_far_future         tracker=future_epoch evaluator=bad_field
bearing_epoch_zero         tracker=out_of_order evaluator=bad_field
bearing_old_epoch          tracker=out_of_order evaluator=-
bearing_wrong_sigma        tracker=sensor_mismatch evaluator=-
bearing_ambiguous_flag     tracker=wrong_sensor_kind evaluator=-
bearing_huge_string        tracker=unknown_sensor evaluator=bad_field
polar_for_bearing_sensor   tracker=wrong_sensor_kind evaluator=-
polar_nan_covariance       tracker=wrong_sensor_kind evaluator=-
measurement_for_bearing_sensor tracker=wrong_sensor_kind evaluator=-
measurement_nan_z          tracker=wrong_sensor_kind evaluator=-
state_unknown_platform     tracker,planner,evaluator=unknown_platform
state_nan_position         tracker,planner,evaluator=non_finite
state_1e300_velocity       tracker,planner,evaluator=out_of_range
state_negative_stamp       tracker,planner,evaluator=bad_stamp
state_far_future           tracker,planner,evaluator=future_epoch
track_wrong_dimension      planner,evaluator=wrong_dimension sim=future_epoch
track_not_pd               planner,evaluator=bad_covariance sim=future_epoch
track_nan_state            planner,evaluator=non_finite sim=future_epoch
track_1e300_state          planner,evaluator=out_of_range sim=future_epoch
track_sample_mismatch      planner,evaluator=wrong_dimension sim=future_epoch
track_huge_sample_claim    planner,evaluator=wrong_dimension sim=future_epoch
track_negative_stamp       planner,evaluator,sim=bad_stamp
track_future_epoch         planner,evaluator,sim=future_epoch
track_bad_filter_kind      planner,evaluator=bad_field sim=future_epoch
command_unknown_platform   sim=unknown_platform
command_nan                sim=non_finite
command_1e300_heading      sim=out_of_range
command_1e300_speed        sim=out_of_range
command_stale_epoch        sim=stale_epoch
command_future_epoch       sim=future_epoch
command_negative_stamp     sim=bad_stamp
selection_unknown_sensor   sim=unexpected_selection
report_nan_costs           evaluator=non_finite
report_length_mismatch     evaluator=wrong_dimension
truth_nan                  evaluator=non_finite
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
        ManoeuvreCommand: "on_command", SensorSelection: "on_selection", TrackEstimate: "on_track"
    },
    "tracker": {
        BearingMeasurement: "on_bearing", PolarMeasurement: "on_polar",
        Measurement: "on_measurement", PlatformState: "on_platform",
    },
    "planner": {TrackEstimate: "on_track", PlatformState: "on_platform"},
    "evaluator": {
        GroundTruth: "on_truth", TrackEstimate: "on_track", PlatformState: "on_platform",
        PlanReport: "on_report", BearingMeasurement: "on_measurement",
        PolarMeasurement: "on_measurement", Measurement: "on_measurement",
        D: "on_diagnostics",
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
            n = sum(len(m.status) for m in messages) if type_key is D else len(messages)
            assert changed == {verdict: n}, f"{node_name} on {name}: {changed}"
    # A member's invalid result message (truth, track, state, report) is a graph fault: the
    # runner stops the run on it instead of waiting for an epoch that never validates.
    verdict = VERDICTS[name].get("evaluator")
    if verdict and verdict.startswith("rejected.") and type_key in RESULT_INPUTS:
        assert nodes["evaluator"].faults


def test_an_incomplete_epoch_is_closed_after_the_timeout(graph, genuine):
    """Platform states announce three measurements, two arrive: the tracker waits
    epoch_timeout, then updates with the two (counted) instead of stalling."""
    params = [Parameter("scenario", value=SCENARIO), Parameter("epoch_timeout", value=0.3)]
    tracker = graph.add(TrackerNode(context=graph.context, parameter_overrides=params))
    for raw in genuine.seen[PlatformState]:
        state = deserialize_message(raw, PlatformState)
        if state.epoch == 1:
            state.epoch_measurement_count = 3
            tracker.guarded(tracker.on_platform, state)
    for raw in genuine.seen[BearingMeasurement]:
        bearing = deserialize_message(raw, BearingMeasurement)
        if bearing.epoch == 1:
            tracker.guarded(tracker.on_bearing, bearing)
    assert tracker.last_epoch == 0 and len(tracker.epochs[1].measurements) == 2
    start = time.monotonic()
    assert graph.spin_until(lambda: tracker.last_epoch == 1, timeout=5.0)
    assert 0.25 <= time.monotonic() - start < 2.0
    assert tracker.counters.counts["incomplete_epochs"] == 1
    assert tracker.counters.counts["updates"] == 1
    assert not tracker.epochs


RESULT_INPUTS = (GroundTruth, TrackEstimate, PlatformState, PlanReport)
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


def test_the_evaluator_gives_up_on_plan_reports_only_after_its_grace(graph):
    """Missing plan reports (a dead planner) stop blocking completion report_grace_s after the
    sim finished: 1 s in one process, longer between processes (a participant that missed the
    planner's first discovery announcements hears the next one about 3 s later)."""
    from activetrack_bringup.runner import REPORT_GRACE_PROCESSES_S

    assert REPORT_GRACE_PROCESSES_S > 3.0
    sc = load_scenario(SCENARIO)
    kw = {"context": graph.context, "start_parameter_services": False}
    quick = graph.add(EvaluatorNode(sc, **kw))
    patient = graph.add(EvaluatorNode(sc, report_grace_s=REPORT_GRACE_PROCESSES_S, **kw))
    for node in (quick, patient):
        assert node.expects_reports and not node._reports_given_up()  # sim not finished
        node.sim_finished_at = time.monotonic() - 2.0
    assert quick._reports_given_up() and not patient._reports_given_up()
    assert "plan report missing" in patient.missing() and "plan report" not in quick.missing()
