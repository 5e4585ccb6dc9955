"""A viewer started before a run sees all of it (``activetrack run --wait-for N|TOPIC``, the
sim's ``hold`` parameter), and every run says which DDS domain and discovery range it uses."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import deserialize_message
from rosgraph_msgs.msg import Clock
from tf2_msgs.msg import TFMessage

from activetrack_bringup.bag_io import open_bag
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.inprocess import InProcessGraph
from activetrack_bringup.ros_network import ros_network
from activetrack_bringup.runner import RunIncomplete, run_graph
from msgs_defs.msg import PlatformState
from sim_node.sim_node import SimNode

SCENARIO = "tests/ros/data/short_two_sensors.yaml"  # 8 epochs of 5 s
pytestmark = pytest.mark.ros
# A viewer's reader: reliable, volatile (it gets what is published after it matched).
VIEWER_QOS = QoSProfile(
    history=HistoryPolicy.KEEP_ALL,
    depth=0,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
)


def _bag_messages(bag: Path, topic: str, cls) -> list:
    with open_bag(bag) as b:
        return [deserialize_message(d, cls) for t, _, d in b.messages([topic]) if t == topic]


def test_a_viewer_started_first_sees_the_whole_run_of_node_processes(tmp_path, monkeypatch):
    """The run, in node processes and a namespace, prints its private domain; a viewer that
    joins that domain before the first epoch gets every clock and tf message the run's bag
    holds, epoch 0 included."""
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)  # the run picks a private domain
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    exe = Path(sys.executable).parent / "activetrack"
    summary = tmp_path / "summary.json"
    proc = subprocess.Popen(
        [str(exe), "run", SCENARIO, "--processes", "--namespace", "w27", "--wait-for", "1",
         "--wait-timeout", "120", "--no-plots", "--out", str(tmp_path / "run"),
         "--json", str(summary)],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        line = proc.stdout.readline()
        assert line.startswith("  ROS        domain "), line + proc.stderr.read()
        domain = int(line.split()[2])
        assert domain == 100 + proc.pid % 100 and "private to this run" in line
        assert "discovery LOCALHOST" in line
        clocks, tfs = [], []
        with InProcessGraph(domain_id=domain) as viewer:
            node = viewer.add(Node("viewer", context=viewer.context))
            node.create_subscription(Clock, "/w27/clock", clocks.append, VIEWER_QOS)
            node.create_subscription(TFMessage, "/w27/tf", tfs.append, VIEWER_QOS)
            assert viewer.spin_until(lambda: proc.poll() is not None, timeout=180)
            viewer.spin_until(lambda: False, timeout=0.3)
        out = line + proc.stdout.read()
        assert proc.returncode == 0, out + proc.stderr.read()
    finally:
        proc.kill()
        proc.wait()
    result = json.loads(summary.read_text())
    assert result["complete"] and result["ros"] == {
        "domain_id": domain, "discovery_range": "LOCALHOST", "static_peers": "", "private": True,
    }  # fmt: skip
    bag = tmp_path / "run" / "bag"
    recorded_clocks = _bag_messages(bag, "/w27/clock", Clock)
    recorded_tf = _bag_messages(bag, "/w27/tf", TFMessage)
    assert [c.clock.sec for c in recorded_clocks] == list(range(0, 45, 5))  # epochs 0..8
    assert recorded_tf and all(m.transforms for m in recorded_tf)

    def frames(msgs, before: int = 40):
        """(stamp, frame, x, y) of every transform stamped before the last epoch: the start
        is what --wait-for is about (the last epoch's delivery races the run's shutdown)."""
        return sorted(
            (t.header.stamp.sec, t.child_frame_id, t.transform.translation.x,
             t.transform.translation.y)
            for m in msgs for t in m.transforms if t.header.stamp.sec < before
        )  # fmt: skip

    assert [c.clock.sec for c in clocks if c.clock.sec < 40] == list(range(0, 40, 5))
    assert frames(tfs) == frames(recorded_tf)
    estimates = [f for f in frames(tfs) if f[1].endswith("/estimate")]
    assert [f[0] for f in estimates] == list(range(0, 40, 5))  # the prior's at 0 included


def test_a_viewer_in_the_runs_own_domain_releases_an_in_process_run(tmp_path):
    """In one process: a viewer subscribing to tf before the run gets epoch 0's transforms."""
    seen = []

    def viewer(graph) -> None:
        node = graph.add(Node("viewer", context=graph.context))
        node.create_subscription(TFMessage, "tf", seen.append, VIEWER_QOS)

    result = run_graph(
        SCENARIO, run_dir=tmp_path, record=False, plots=False, wait_for="tf",
        wait_timeout=30.0, before_spin=viewer,
    )  # fmt: skip
    assert result.complete
    stamps = sorted({t.header.stamp.sec for m in seen for t in m.transforms})
    assert stamps == list(range(0, 45, 5))


def test_nobody_to_wait_for_fails_clearly_after_the_timeout(tmp_path):
    start = time.monotonic()
    with pytest.raises(RunIncomplete) as caught:
        run_graph(
            SCENARIO, run_dir=tmp_path, record=False, plots=False, wait_for="2",
            wait_timeout=0.5,
        )  # fmt: skip
    result = caught.value.result
    assert caught.value.exit_code == 1 and time.monotonic() - start < 30
    assert (result.status, result.epochs_completed) == ("timeout", 0)
    assert result.detail == (
        "--wait-for: 2 subscriber node(s) of the graph's topics outside the graph did not join "
        "within 0.5 s (--wait-timeout); the run did not start"
    )


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--wait-for", "0"], "--wait-for: a number of subscribers must be >= 1, got 0"),
        (["--wait-for", "a b"], "--wait-for: a subscriber count or a topic name, got 'a b'"),
        (["--wait-timeout", "3"], "--wait-timeout needs --wait-for"),
        (["--rate", "2"], "--rate: sim seconds per wall second apply in free mode only"),
        (["--filter", "kalman"], "--filter must be one of ["),
    ],
)
def test_bad_run_options_are_one_error_line(tmp_path, capsys, args, message):
    rc = cli_main(["run", SCENARIO, "--out", str(tmp_path / "r"), "--no-bag", *args])
    out, err = capsys.readouterr()
    assert rc == 2 and err.startswith("error: ") and message in err, err
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in out + err


def test_run_prints_its_domain_and_discovery_range(tmp_path, capsys):
    """In one process the run joins the caller's domain (tests: a private one, discovery
    OFF) and says so before the first epoch; summary.json keeps it."""
    rc = cli_main(["run", SCENARIO, "--out", str(tmp_path), "--no-bag", "--no-plots",
                   "--json", str(tmp_path / "s.json")])  # fmt: skip
    out = capsys.readouterr().out
    domain = int(os.environ["ROS_DOMAIN_ID"])
    assert rc == 0
    assert out.splitlines()[0] == (
        f"  ROS        domain {domain}, discovery OFF; tools join with ROS_DOMAIN_ID={domain} "
        f"ROS_AUTOMATIC_DISCOVERY_RANGE=OFF (activetrack ros ... --domain {domain})"
    )
    saved = json.loads((tmp_path / "s.json").read_text())["ros"]
    assert saved == {"domain_id": domain, "discovery_range": "OFF", "static_peers": "",
                     "private": False}  # fmt: skip


def test_network_of_node_processes(monkeypatch):
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    monkeypatch.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")
    net = ros_network(processes=True)
    assert (net.domain_id, net.discovery_range, net.private) == (
        100 + os.getpid() % 100, "LOCALHOST", True,
    )  # fmt: skip
    # Nodes on other hosts: the caller's range (it must reach them), the given domain.
    monkeypatch.setenv("ROS_DOMAIN_ID", "17")
    net = ros_network(processes=True, every_node_here=False)
    assert (net.domain_id, net.discovery_range, net.private) == (17, "SUBNET", False)
    monkeypatch.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE")
    assert ros_network(processes=False).discovery_range == "SUBNET"  # Jazzy's default


def test_a_held_sim_publishes_nothing_until_released(graph):
    """3 outside subscribers asked, one there: held; 0 releases it; then the parameters are
    fixed. A topic nobody outside reads holds it too."""
    params = [Parameter("scenario", value=SCENARIO), Parameter("wait_for_subscribers", value=3)]
    sim = graph.add(SimNode(context=graph.context, parameter_overrides=params))
    states = []
    node = graph.add(Node("probe", context=graph.context))
    qos = QoSProfile(
        depth=100,
        reliability=ReliabilityPolicy.RELIABLE,
        durability=DurabilityPolicy.TRANSIENT_LOCAL,
    )
    node.create_subscription(PlatformState, "activetrack/platform_states", states.append, qos)
    graph.spin_until(lambda: False, timeout=0.5)
    assert states == [] and sim.hold.state == "held"
    # One there, but not on tf: still held.
    change = [Parameter("wait_for_subscribers", value=1), Parameter("wait_for_topic", value="tf")]
    assert all(r.successful for r in sim.set_parameters(change))
    graph.spin_until(lambda: False, timeout=0.3)
    assert states == [] and sim.hold.state == "held"
    bad = sim.set_parameters([Parameter("wait_for_topic", value="a b")])[0]
    assert not bad.successful and "must match" in bad.reason
    assert sim.set_parameters([Parameter("wait_for_topic", value="activetrack/platform_states")])[
        0
    ].successful
    assert graph.spin_until(lambda: len(states) == 2, timeout=10.0)  # after SETTLE_S
    assert [s.epoch for s in states] == [0, 0]
    again = sim.set_parameters([Parameter("wait_for_subscribers", value=2)])[0]
    assert not again.successful and "the run has started" in again.reason
    assert sim.get_parameter("wait_for_subscribers").value == 1


def test_a_bad_wait_for_stops_the_sim_at_start_up():
    exe = Path(sys.executable).parent / "sim_node"
    proc = subprocess.run(
        [str(exe), "--ros-args", "-p", f"scenario:={SCENARIO}", "-p", "wait_for_topic:=a b"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert proc.returncode == 2, proc.stderr
    assert "parameter 'wait_for_topic' must match" in proc.stderr and "Traceback" not in proc.stderr


def test_a_sim_waits_for_the_nodes_it_names(graph):
    """wait_for_nodes (the launch file's evaluator and recorder): any other subscriber does
    not release it, the named one does, inside the graph's own names too."""
    params = [Parameter("scenario", value=SCENARIO),
              Parameter("wait_for_nodes", value="activetrack_recorder")]  # fmt: skip
    sim = graph.add(SimNode(context=graph.context, parameter_overrides=params))
    qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
    other = graph.add(Node("other", context=graph.context))
    other.create_subscription(Clock, "clock", lambda _m: None, qos)
    graph.spin_until(lambda: False, timeout=0.5)
    assert sim.hold.state == "held"
    clocks = []
    named = graph.add(Node("activetrack_recorder", context=graph.context))
    named.create_subscription(Clock, "clock", clocks.append, qos)
    assert graph.spin_until(lambda: clocks, timeout=10.0)  # after SETTLE_S
    assert sim.hold.state == "started" and clocks[0].clock.sec == 0
