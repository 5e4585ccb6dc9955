"""``activetrack ros graph|echo|hz|param|tf`` against a running graph: node processes in a
namespace (a free run, slowed down so that it outlives the tools), on the tests' private
domain. Their output is checked against what the nodes declare and publish: the graph's own
topic table and QoS, the nodes' parameter specifications, and the run's bag."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from types import SimpleNamespace

import pytest
import yaml
from geometry_msgs.msg import Point, TransformStamped, Vector3
from rclpy.serialization import deserialize_message
from tf2_msgs.msg import TFMessage

from activetrack_bringup.bag_io import open_bag
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.ros_tools.hz import RateWindow
from activetrack_bringup.ros_tools.messages import field, message_type, to_plain, to_yaml
from activetrack_bringup.ros_tools.session import ToolError, ToolSession
from activetrack_bringup.ros_tools.tf_tree import Link, tree_text
from activetrack_ros.graph import GRAPH_TOPICS, writer_qos
from msgs_defs.msg import PlatformState
from sim_node.sim_node import PARAMS as SIM_PARAMS
from tracker_node.tracker_node import FILTER
from tracker_node.tracker_node import PARAMS as TRACKER_PARAMS

SCENARIO = "tests/ros/data/short_two_sensors.yaml"  # epochs of 5 s, 2 platforms
NS = "rt27"
RATE = 0.4  # sim seconds per wall second
STEPS = 60  # the run lasts 750 s unless stopped: it outlives the module's tools on a busy machine
pytestmark = [pytest.mark.ros, pytest.mark.slow]
OURS = ("sim_node", "tracker_node", "planner_node", "activetrack_evaluator", "activetrack_recorder")


@pytest.fixture(scope="module")
def live(tmp_path_factory):
    """The graph in node processes under /rt27 on this run's private domain."""
    saved = os.environ.get("ROS_AUTOMATIC_DISCOVERY_RANGE")
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"  # the tools' own participants
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    out = tmp_path_factory.mktemp("live")
    scenario = yaml.safe_load(Path(SCENARIO).read_text()) | {"steps": STEPS}
    (out / "scenario.yaml").write_text(yaml.safe_dump(scenario))
    proc = subprocess.Popen(
        [str(Path(sys.executable).parent / "activetrack"), "run", str(out / "scenario.yaml"),
         "--processes",
         "--namespace", NS, "--mode", "free", "--rate", str(RATE), "--no-plots",
         "--out", str(out / "run")],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        # Ctrl-C as at a terminal, even when the suite runs as a background job (SIGINT ignored)
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )  # fmt: skip
    line = proc.stdout.readline()
    try:
        assert f"domain {os.environ['ROS_DOMAIN_ID']}, discovery LOCALHOST" in line, line
        with ToolSession(namespace=NS) as s:  # the node processes take a few seconds to start
            ours = {f"/{NS}/{n}" for n in OURS}
            assert s.wait_for_graph(lambda: ours <= set(s.nodes()), timeout=60), s.nodes()
        yield SimpleNamespace(
            proc=proc, bag=out / "run" / "bag", scenario=str(out / "scenario.yaml"), echoed={}
        )
    finally:
        if proc.poll() is None:
            proc.kill()
        proc.wait()
        if saved is None:
            os.environ.pop("ROS_AUTOMATIC_DISCOVERY_RANGE", None)
        else:
            os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = saved


def ros(capsys, *argv) -> tuple[int, str, str]:
    """``activetrack ros ...`` in this process: (exit code, stdout, stderr)."""
    rc = cli_main(["ros", *map(str, argv)])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return rc, out, err


def param(capsys, *argv) -> tuple[int, str, str]:
    """``activetrack ros param ...`` on the live graph, waiting up to 30 s for each answer: a
    fresh tool participant finds a node's services well within the tool's 5-s default on a
    quiet host, but the suite's other worker can make discovery slower (a dump timed out once
    in CI)."""
    return ros(capsys, "param", *argv, "--timeout", "30")


def test_graph_lists_the_nodes_topics_types_and_qos_they_publish(live, capsys):
    rc, out, _ = ros(capsys, "graph", "--namespace", NS, "--yaml")
    assert rc == 0
    graph = yaml.safe_load(out)
    assert set(graph["nodes"]) == {f"/{NS}/{n}" for n in OURS}
    published = {name: t for name, t in graph["topics"].items() if t["publishers"]}
    assert {f"/{NS}/clock", f"/{NS}/tf", f"/{NS}/activetrack/platform_states"} <= set(published)
    for name, t in published.items():
        relative = name.removeprefix(f"/{NS}/")
        assert t["types"] == [GRAPH_TOPICS[relative]], name
        qos = writer_qos(relative)
        expected = f"{qos.reliability.name.lower()} {qos.durability.name.lower()}"
        assert {q for _, q in t["publishers"]} == {expected}, name
    states = graph["topics"][f"/{NS}/activetrack/platform_states"]
    assert [n for n, _ in states["publishers"]] == [f"/{NS}/sim_node"]
    assert {n for n, _ in states["subscribers"]} == {
        f"/{NS}/{n}" for n in ("tracker_node", "planner_node", "activetrack_evaluator",
                                "activetrack_recorder")
    }  # fmt: skip


def test_param_list_reaches_every_node_evaluator_and_recorder_included(live, capsys):
    rc, out, _ = param(capsys, "list", "--namespace", NS)
    assert rc == 0 and "no parameter services" not in out
    listed: dict[str, list[str]] = {}
    for line in out.splitlines():
        if not line.startswith("  "):
            node = line.rstrip(":")
            listed[node] = []
        else:
            listed[node].append(line.strip())
    assert set(listed) >= {f"/{NS}/activetrack_evaluator", f"/{NS}/activetrack_recorder"}
    assert set(listed[f"/{NS}/sim_node"]) >= {s.name for s in SIM_PARAMS} | {"use_sim_time"}
    assert {"bag", "topics", "depth", "clock_lead"} <= set(listed[f"/{NS}/activetrack_recorder"])


def test_param_get_set_describe_as_ros2_param(live, capsys):
    domain = os.environ["ROS_DOMAIN_ID"]
    rc, out, _ = param(capsys, "get", f"/{NS}/sim_node", "mode", "--domain", domain)
    assert (rc, out) == (0, "String value is: free\n")
    # An integer for a float parameter, at run time (command_timeout: no effect in free mode).
    rc, out, _ = param(capsys, "set", "sim_node", "command_timeout", "7", "--namespace", NS)
    assert (rc, out) == (0, "Set parameter successful\n")
    rc, out, _ = param(capsys, "get", "sim_node", "command_timeout", "--namespace", NS)
    assert (rc, out) == (0, "Double value is: 7.0\n")
    rc, out, _ = param(capsys, "set", "sim_node", "use_sim_time", "true", "--namespace", NS)
    assert rc == 1
    assert out == "Setting parameter failed: Trying to set a read-only parameter: use_sim_time.\n"
    rc, out, _ = param(capsys, "describe", "sim_node", "rate", "use_sim_time",
                     "--namespace", NS)  # fmt: skip
    assert rc == 0
    assert out.splitlines()[:6] == [
        "Parameter name: rate",
        "  Type: double",
        f"  Description: {next(s for s in SIM_PARAMS if s.name == 'rate').description}",
        "  Constraints:",
        "    Min value: 0.001",
        "    Max value: 1000000.0",
    ]
    assert "Parameter name: use_sim_time" in out and "    Read only: true" in out
    rc, _, err = param(capsys, "get", "sim_node", "nonesuch", "--namespace", NS)
    assert rc == 2 and err == f"error: /{NS}/sim_node has no parameter ['nonesuch']\n"


def test_param_dump_is_a_params_file_of_what_the_node_holds(live, capsys, tmp_path):
    rc, out, err = param(capsys, "dump", "tracker_node", "--namespace", NS)
    assert rc == 0, err
    dumped = yaml.safe_load(out)[f"/{NS}/tracker_node"]["ros__parameters"]
    given = {"scenario": live.scenario, "run": -1, "mode": "free"}
    for spec in (*TRACKER_PARAMS, FILTER):
        assert dumped[spec.name] == given.get(spec.name, spec.default), spec.name
    assert dumped["use_sim_time"] is False
    # The dump is a params file: a tracker in that namespace starts with the same values.
    from activetrack_bringup.inprocess import InProcessGraph
    from tracker_node.tracker_node import TrackerNode

    path = tmp_path / "tracker.yaml"
    path.write_text(out)
    args = ["--ros-args", "--params-file", str(path), "-r", f"__ns:=/{NS}"]
    saved = os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"]
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "OFF"  # not a node of the live graph
    try:
        with InProcessGraph(args=args) as g:
            node = g.add(TrackerNode(context=g.context, start_parameter_services=False))
            assert {n: node.get_parameter(n).value for n in dumped} == dumped
    finally:
        os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = saved


def echo_first_state(live, capsys) -> None:
    """``echo --once`` of the platform states, kept for the comparison with the bag."""
    rc, out, _ = ros(capsys, "echo", "activetrack/platform_states", "--once", "--namespace", NS)
    assert rc == 0 and out.endswith("\n---\n")
    live.echoed["platform_states"] = yaml.safe_load(out.removesuffix("---\n"))


def test_echo_once_prints_the_first_platform_state_as_yaml(live, capsys):
    echo_first_state(live, capsys)
    assert set(live.echoed["platform_states"]) >= {"header", "platform_id", "epoch"}


def test_echo_count_and_field(live, capsys):
    rc, out, _ = ros(capsys, "echo", "clock", "--count", "3", "--field", "clock",
                     "--namespace", NS)  # fmt: skip
    assert rc == 0
    docs = [yaml.safe_load(d) for d in out.split("---\n") if d.strip()]
    assert len(docs) == 3 and all(set(d) == {"sec", "nanosec"} for d in docs)
    times = [d["sec"] + 1e-9 * d["nanosec"] for d in docs]
    assert times == sorted(times)
    rc, out, err = ros(capsys, "echo", "clock", "--once", "--field", "clock.minutes",
                       "--namespace", NS)  # fmt: skip
    assert rc == 2 and "--field clock.minutes: rosgraph_msgs/msg/Clock has no 'minutes'" in err
    rc, _, err = ros(capsys, "echo", "nonesuch", "--once", "--wait", "0.5", "--namespace", NS)
    assert (
        rc == 1 and err == f"error: no publisher of /{NS}/nonesuch appeared within 0.5 s (--wait)\n"
    )


def test_hz_measures_the_free_runs_clock(live, capsys):
    """In free mode the sim publishes /clock every tick (0.01 s of wall time): about 100 Hz."""
    tick = next(s for s in SIM_PARAMS if s.name == "tick").default
    rc, out, _ = ros(capsys, "hz", "clock", "--duration", "3", "--namespace", NS)
    assert rc == 0
    last = out.strip().splitlines()[-2:]
    rate = float(last[0].removeprefix("average rate: "))
    assert 0.4 / tick < rate < 1.2 / tick, out
    assert int(last[1].split("window: ")[1]) > 50


def tf_tree(live, capsys) -> list[str]:
    """``tf`` over two epochs at 0.4x (12.5 s each: one can pass while the tool joins the
    graph); platform p1's line is kept for the comparison with the bag."""
    rc, out, _ = ros(capsys, "tf", "--duration", "26", "--namespace", NS)
    assert rc == 0
    lines = out.splitlines()
    live.echoed["tf_p1"] = next(line for line in lines if "platform/p1  (" in line)
    return lines


def test_tf_prints_the_tree_with_the_latest_transforms(live, capsys):
    lines = tf_tree(live, capsys)
    assert lines[1] == "world"
    children = {line.split("  (")[0].lstrip("├└─│ ") for line in lines[2:]}
    assert children == {"platform/p1", "sensor/s1", "platform/p2", "sensor/s2",
                        "target/t1/truth", "target/t1/estimate"}  # fmt: skip
    assert "│   └── sensor/s1  (x 0.000 y 0.000 z 0.000 m, yaw 0.00 deg; static)" in lines


def test_the_tools_output_matches_the_runs_bag(live, capsys):
    """Stop the run (Ctrl-C: its bag is closed), then compare what echo and tf printed with
    the messages the run recorded (run alone, this test asks the tools itself)."""
    if "platform_states" not in live.echoed:
        echo_first_state(live, capsys)
    if "tf_p1" not in live.echoed:
        tf_tree(live, capsys)
    live.proc.send_signal(signal.SIGINT)
    assert live.proc.wait(timeout=60) == 130
    with open_bag(live.bag) as bag:
        states = [
            deserialize_message(d, PlatformState)
            for t, _, d in bag.messages([f"/{NS}/activetrack/platform_states"])
        ]
        tfs = [deserialize_message(d, TFMessage) for _, _, d in bag.messages([f"/{NS}/tf"])]
    assert live.echoed["platform_states"] == to_plain(states[0])
    p1 = live.echoed["tf_p1"]
    stamp = float(p1.split("stamp ")[1].split(" s")[0])
    t = next(
        t for m in tfs for t in m.transforms
        if t.child_frame_id == "platform/p1" and t.header.stamp.sec == round(stamp)
    )  # fmt: skip
    assert f"x {t.transform.translation.x:.3f} y {t.transform.translation.y:.3f}" in p1


# --- the pieces, without a graph -----------------------------------------------------------


def test_message_as_plain_data_yaml_and_fields():
    msg = PlatformState(
        platform_id="p1", epoch=3, sensor_ids=["s1", "s2"], heading=0.25,
        position=Point(x=1.5, y=-2.0), velocity=Vector3(x=3.0), graph_auth=[1, 2, 255],
    )  # fmt: skip
    data = to_plain(msg)
    assert list(data) == list(PlatformState.get_fields_and_field_types())
    assert data["position"] == {"x": 1.5, "y": -2.0, "z": 0.0}
    assert data["graph_auth"] == [1, 2, 255] and data["sensor_ids"] == ["s1", "s2"]
    assert field(data, "position.y") == -2.0 and field(data, "sensor_ids.1") == "s2"
    with pytest.raises(ToolError, match=r"has no 'height' \(there: \['x', 'y', 'z'\]\)"):
        field(data, "position.height", "PlatformState")
    text = to_yaml(data)
    assert "position:\n  x: 1.5\n  y: -2.0\n  z: 0.0\n" in text
    assert "sensor_ids:\n- s1\n- s2\n" in text and yaml.safe_load(text) == data
    assert to_yaml(field(data, "epoch")) == "3"
    assert message_type("msgs_defs/PlatformState") is PlatformState
    with pytest.raises(ToolError, match="not installed here"):
        message_type("nonesuch_msgs/msg/Thing")


def test_rate_window_figures():
    window = RateWindow(size=4)
    for t in (0.0, 0.1, 0.3, 0.4, 0.5, 0.6):  # the window keeps the last 4 gaps
        window.add(t)
    r = window.figures()
    assert r.window == 4 and window.count == 6
    assert (
        math.isclose(r.rate, 4 / 0.5) and math.isclose(r.min_s, 0.1) and math.isclose(r.max_s, 0.2)
    )
    mean = 0.5 / 4
    std = math.sqrt(sum((g - mean) ** 2 for g in (0.2, 0.1, 0.1, 0.1)) / 4)
    assert math.isclose(r.std_s, std)
    assert RateWindow().figures() is None


def test_tree_text_draws_parents_children_and_ages():
    def link(parent, child, x, yaw, stamp, static=False):
        t = TransformStamped()
        t.header.frame_id, t.child_frame_id = parent, child
        t.header.stamp.sec = stamp
        t.transform.translation.x = x
        t.transform.rotation.z, t.transform.rotation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        return Link.of(t, static)

    links = {
        "a": link("world", "a", 1.0, math.pi / 2, 10),
        "b": link("world", "b", 2.0, 0.0, 8),
        "s": link("a", "s", 0.0, 0.0, 0, static=True),
    }
    assert tree_text(links, now=12.0).splitlines() == [
        "world",
        "├── a  (x 1.000 y 0.000 z 0.000 m, yaw 90.00 deg; stamp 10.000 s, age 2.000 s)",
        "│   └── s  (x 0.000 y 0.000 z 0.000 m, yaw 0.00 deg; static)",
        "└── b  (x 2.000 y 0.000 z 0.000 m, yaw 0.00 deg; stamp 8.000 s, age 4.000 s)",
    ]


def test_an_unreachable_node_is_one_error_line(capsys):
    start = time.monotonic()
    rc, _, err = ros(capsys, "param", "list", "/nobody_here", "--timeout", "0.5")
    assert rc == 1 and time.monotonic() - start < 20
    assert err == (
        "error: node /nobody_here answers no parameter services within 0.5 s (is it on this "
        "domain and namespace? --domain, --namespace)\n"
    )
