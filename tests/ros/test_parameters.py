"""Node parameters tell the truth: described, typed, ranged, read-only where a running node
cannot change them; a change is applied or refused with the reason, through the nodes' real
parameter services (what `ros2 param describe/get/set` call), and params files work."""

import subprocess
import sys
from pathlib import Path

import pytest
from geometry_msgs.msg import PoseWithCovarianceStamped
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from activetrack_bringup.inprocess import InProcessGraph
from planner_node.planner_node import PlannerNode
from sim_node.sim_node import SimNode
from tracker_node.tracker_node import TrackerNode

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
READ_ONLY = {
    "sim_node": {"scenario", "run", "mode", "frame_id", "tick", "expect_tracker"},
    "tracker_node": {"scenario", "run", "mode", "frame_id", "particles", "filter"},
    "planner_node": {"scenario", "run", "frame_id"},
}
RCLPY_OWN = {"use_sim_time", "start_type_description_service"}
CHANGEABLE = {
    "sim_node": {
        "rate",
        "command_timeout",
        "tracks_timeout",
        "exit_when_done",
        "wait_for_subscribers",
        "wait_for_topic",
        "wait_for_nodes",
    },
    "tracker_node": {"cloud_size", "epoch_timeout"},
    "planner_node": set(),
}


def _call(graph: InProcessGraph, future, timeout: float = 5.0):
    assert graph.spin_until(future.done, timeout=timeout), "parameter service did not answer"
    return future.result()


@pytest.fixture
def nodes(graph):
    """The three nodes (sim in free mode) with their parameter services, and a client node."""

    def params(**extra):
        return [Parameter(k, value=v) for k, v in {"scenario": SCENARIO, **extra}.items()]

    made = {
        "sim_node": graph.add(
            SimNode(context=graph.context, parameter_overrides=params(mode="free", rate=2.0))
        ),
        "tracker_node": graph.add(TrackerNode(context=graph.context, parameter_overrides=params())),
        "planner_node": graph.add(PlannerNode(context=graph.context, parameter_overrides=params())),
    }
    tool = graph.add(Node("param_tool", context=graph.context))
    clients = {name: AsyncParameterClient(tool, name) for name in made}
    for c in clients.values():
        assert c.wait_for_services(timeout_sec=5.0)
    return made, clients


def test_every_parameter_is_described_typed_and_ranged(graph, nodes):
    _, clients = nodes
    for name, client in clients.items():
        listed = _call(graph, client.list_parameters()).result.names
        ours = [n for n in listed if n not in RCLPY_OWN]
        assert set(ours) == READ_ONLY[name] | CHANGEABLE[name]
        described = _call(graph, client.describe_parameters(ours)).descriptors
        for d in described:
            assert len(d.description) > 20, (name, d.name)
            assert d.type != ParameterType.PARAMETER_NOT_SET
            assert d.read_only == (d.name in READ_ONLY[name]), (name, d.name)
            if d.type == ParameterType.PARAMETER_DOUBLE:
                r = d.floating_point_range[0]
                assert 0 < r.from_value < r.to_value, (name, d.name)
    rate = _call(graph, clients["sim_node"].describe_parameters(["rate"])).descriptors[0]
    assert (rate.floating_point_range[0].from_value, rate.floating_point_range[0].to_value) == (
        1e-3,
        1e6,
    )
    mode = _call(graph, clients["sim_node"].describe_parameters(["mode"])).descriptors[0]
    assert "lockstep" in mode.additional_constraints and "free" in mode.additional_constraints


def test_changes_a_node_can_apply_are_applied(graph, nodes):
    made, clients = nodes
    sim, tracker = made["sim_node"], made["tracker_node"]
    before = sim.sim_time_now()
    result = _call(
        graph,
        clients["sim_node"].set_parameters(
            [Parameter("rate", value=50.0), Parameter("command_timeout", value=2.5)]
        ),
    ).results
    assert [r.successful for r in result] == [True, True]
    assert (sim.rate, sim.timeout) == (50.0, 2.5)
    # Sim time stays continuous across the change and then runs at the new rate.
    assert sim.sim_time_now() >= before
    got = _call(graph, clients["sim_node"].get_parameters(["rate", "command_timeout"])).values
    assert [v.double_value for v in got] == [50.0, 2.5]
    ok = _call(graph, clients["tracker_node"].set_parameters([Parameter("cloud_size", value=7)]))
    assert ok.results[0].successful and tracker.cloud_size == 7


@pytest.mark.parametrize(
    ("node", "param", "value", "reason"),
    [
        ("sim_node", "mode", "lockstep", "read-only"),
        ("sim_node", "scenario", "scenarios/default.yaml", "read-only"),
        ("sim_node", "rate", 0.0, "out of range Min: 0.001, Max: 1000000.0"),
        ("sim_node", "rate", float("nan"), "out of range"),
        ("sim_node", "rate", "fast", "type"),
        ("sim_node", "command_timeout", -1.0, "out of range"),
        ("tracker_node", "filter", "ekf", "read-only"),
        ("tracker_node", "cloud_size", 10**9, "out of range"),
        ("planner_node", "frame_id", "map", "read-only"),
    ],
)
def test_other_changes_are_refused_with_the_reason(graph, nodes, node, param, value, reason):
    made, clients = nodes
    before = made[node].get_parameter(param).value
    result = _call(graph, clients[node].set_parameters([Parameter(param, value=value)]))
    r = result.results[0]
    assert not r.successful
    assert reason in r.reason, r.reason
    got = _call(graph, clients[node].get_parameters([param])).values[0]
    # What get reports is what the node runs with.
    assert Parameter.from_parameter_msg(ParameterMsg(name=param, value=got)).value == before


def test_rate_is_refused_in_lockstep_mode(graph):
    sim = graph.add(
        SimNode(context=graph.context, parameter_overrides=[Parameter("scenario", value=SCENARIO)])
    )
    tool = graph.add(Node("param_tool", context=graph.context))
    client = AsyncParameterClient(tool, "sim_node")
    assert client.wait_for_services(timeout_sec=5.0)
    r = _call(graph, client.set_parameters([Parameter("rate", value=3.0)])).results[0]
    assert not r.successful and "free mode only" in r.reason
    assert sim.rate == 1.0 and sim.get_parameter("rate").value == 1.0


def test_params_file_sets_node_and_wildcard_parameters(tmp_path):
    """`--ros-args --params-file`: a node's own section and ``/**`` for all; an integer for a
    float parameter is taken as that float; the frame reaches the headers."""
    path = tmp_path / "params.yaml"
    path.write_text(
        "/**:\n  ros__parameters:\n    scenario: " + SCENARIO + "\n    frame_id: map\n"
        "sim_node:\n  ros__parameters:\n    mode: free\n    rate: 4\n"
        "tracker_node:\n  ros__parameters:\n    cloud_size: 12\n"
    )
    with InProcessGraph(args=["--ros-args", "--params-file", str(path)]) as g:
        sim = g.add(SimNode(context=g.context))
        tracker = g.add(TrackerNode(context=g.context))
        assert (sim.mode, sim.rate, sim.frame_id) == ("free", 4.0, "map")
        assert (tracker.cloud_size, tracker.frame_id) == (12, "map")
        seen = []
        g.add(Node("probe", context=g.context)).create_subscription(
            PoseWithCovarianceStamped, "activetrack/track_pose", seen.append, 10
        )
        tracker.publish_tracks(tracker.core.snapshot())
        assert g.spin_until(lambda: seen, timeout=5.0)
        assert seen[0].header.frame_id == "map"


@pytest.mark.parametrize(
    ("line", "message"),
    [
        ("mode: fast", "parameter 'mode' must be one of ['lockstep', 'free'], got 'fast'"),
        ("rate: -2.0", "parameter 'rate' must be in [0.001, 1000000.0], got -2.0"),
        ("frame_id: /world", "parameter 'frame_id' must match"),
        ("tick: fast", "parameter 'tick' must be a float, got str 'fast'"),
    ],
)
def test_a_bad_params_file_stops_the_node_before_it_publishes(tmp_path, line, message):
    path = tmp_path / "params.yaml"
    path.write_text(f"sim_node:\n  ros__parameters:\n    scenario: {SCENARIO}\n    {line}\n")
    exe = Path(sys.executable).parent / "sim_node"
    proc = subprocess.run(
        [str(exe), "--ros-args", "--params-file", str(path)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2, proc.stderr
    assert message in proc.stderr
    assert "Traceback" not in proc.stderr


def test_an_integer_for_a_float_parameter_is_taken_at_run_time(graph, nodes):
    """What the README promises for start-up holds for `ros2 param set /sim_node rate 5` too:
    the integer is taken as that float (rclpy alone refuses it as the wrong type)."""
    made, clients = nodes
    sim = made["sim_node"]
    result = _call(
        graph,
        clients["sim_node"].set_parameters(
            [Parameter("rate", value=5), Parameter("command_timeout", value=3)]
        ),
    ).results
    assert [r.successful for r in result] == [True, True], [r.reason for r in result]
    assert (sim.rate, sim.timeout) == (5.0, 3.0)
    assert isinstance(sim.rate, float) and isinstance(sim.timeout, float)
    got = _call(graph, clients["sim_node"].get_parameters(["rate", "command_timeout"])).values
    double = ParameterType.PARAMETER_DOUBLE
    assert [(v.type, v.double_value) for v in got] == [(double, 5.0), (double, 3.0)]
    # Out of range stays refused as an integer too; an integer parameter takes no float.
    r = _call(graph, clients["sim_node"].set_parameters([Parameter("rate", value=0)])).results[0]
    assert not r.successful and "out of range" in r.reason and sim.rate == 5.0
    tracker = clients["tracker_node"]
    r = _call(graph, tracker.set_parameters([Parameter("cloud_size", value=7.0)])).results[0]
    assert not r.successful and "type" in r.reason


@pytest.fixture
def every_node(graph, nodes, tmp_path):
    """The three nodes, the evaluator and the recorder, with parameter clients for all."""
    from activetrack.scenarios import load_scenario
    from activetrack_bringup.bag import BagRecorder
    from activetrack_bringup.evaluator import EvaluatorNode

    made, clients = nodes
    made = dict(made)
    made["activetrack_evaluator"] = graph.add(
        EvaluatorNode(load_scenario(SCENARIO), context=graph.context)
    )
    made["activetrack_recorder"] = graph.add(BagRecorder(tmp_path / "bag", context=graph.context))
    tool = graph.add(Node("param_tool_2", context=graph.context))
    clients = {name: AsyncParameterClient(tool, name) for name in made}
    for c in clients.values():
        assert c.wait_for_services(timeout_sec=5.0)
    return made, clients


def test_use_sim_time_is_described_and_refused_on_every_node(graph, every_node):
    """rclpy's use_sim_time, writable and undescribed by default, froze a free run's clock
    when set: on every node of the graph it is read-only, described, and stays false."""
    made, clients = every_node
    for name, client in clients.items():
        d = _call(graph, client.describe_parameters(["use_sim_time"])).descriptors[0]
        assert d.read_only and "wall time" in d.description, name
        assert d.type == ParameterType.PARAMETER_BOOL
        r = _call(graph, client.set_parameters([Parameter("use_sim_time", value=True)]))
        assert not r.results[0].successful and "read-only" in r.results[0].reason, name
        got = _call(graph, client.get_parameters(["use_sim_time"])).values[0]
        assert got.bool_value is False and not made[name].get_clock().ros_time_is_active


def test_evaluator_and_recorder_answer_parameter_services(graph, every_node, tmp_path):
    _, clients = every_node
    expected = {
        "activetrack_evaluator": {
            "scenario", "run", "frame_id", "report_grace", "lost_grace", "summary",
            "exit_when_done",
        },
        "activetrack_recorder": {"bag", "topics", "depth", "clock_lead"},
    }  # fmt: skip
    for name, ours in expected.items():
        listed = set(_call(graph, clients[name].list_parameters()).result.names) - RCLPY_OWN
        assert listed == ours, name
        for d in _call(graph, clients[name].describe_parameters(sorted(ours))).descriptors:
            assert len(d.description) > 20, (name, d.name)
            assert d.read_only == (d.name != "exit_when_done"), (name, d.name)
    bag = _call(graph, clients["activetrack_recorder"].get_parameters(["bag"])).values[0]
    assert bag.string_value == str(tmp_path / "bag")


def test_use_sim_time_true_at_start_up_stops_the_node():
    exe = Path(sys.executable).parent / "sim_node"
    proc = subprocess.run(
        [str(exe), "--ros-args", "-p", f"scenario:={SCENARIO}", "-p", "use_sim_time:=true"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2, proc.stderr
    assert "parameter 'use_sim_time' must be false for sim_node" in proc.stderr
    assert "Traceback" not in proc.stderr
