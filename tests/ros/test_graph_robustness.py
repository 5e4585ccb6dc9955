"""Bad input on every topic is rejected, counted and logged; a dying planner is survived."""

import math

import numpy as np
import pytest
from builtin_interfaces.msg import Time
from geometry_msgs.msg import Point, Vector3
from rclpy.node import Node
from rclpy.parameter import Parameter
from std_msgs.msg import Header

from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros.graph import qos_for
from msgs_defs.msg import (
    BearingMeasurement,
    ManoeuvreCommand,
    PlatformState,
    PolarMeasurement,
    SensorSelection,
    TrackEstimate,
)
from planner_node.planner_node import PlannerNode

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


def _header(seconds: float) -> Header:
    return Header(stamp=Time(sec=int(seconds), nanosec=round((seconds % 1) * 1e9)))


def _bearing(epoch, stamp=None, sensor_id="s1", bearing=0.5, position=(0.0, 0.0)):
    return BearingMeasurement(
        header=_header(epoch * 5.0 if stamp is None else stamp),
        platform_id="p1",
        sensor_id=sensor_id,
        epoch=epoch,
        epoch_measurement_count=2,
        sensor_position=Point(x=position[0], y=position[1]),
        sensor_velocity=Vector3(),
        bearing=bearing,
        sigma=0.01,
        detected=True,
    )


def _bad_messages(epoch: int) -> list:
    """One message per kind of bad input, aimed at the epoch after ``epoch``."""
    nxt = epoch + 1
    bad_cov = TrackEstimate(
        header=_header(0.0),
        target_id="t1",
        epoch=999,
        filter_kind="pf",
        state_names=["x", "xdot", "y", "ydot"],
        state=[0.0, 0.0, 0.0, 0.0],
        covariance=[
            1.0,
            2.0,
            0.0,
            0.0,
            2.0,
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
            0.0,
            0.0,
            0.0,
            0.0,
            1.0,
        ],  # eigenvalues -1, 3, 1, 1
    )
    return [
        ("tracker", "non_finite", _bearing(nxt, bearing=math.nan)),
        ("tracker", "non_finite", _bearing(nxt, position=(math.inf, 0.0))),
        ("tracker", "unknown_sensor", _bearing(nxt, sensor_id="s9")),
        ("tracker", "out_of_order", _bearing(epoch)),
        ("tracker", "bad_stamp", _bearing(nxt, stamp=999.0)),
        ("tracker", "future_epoch", _bearing(nxt + 3)),
        (
            "tracker",
            "wrong_sensor_kind",
            PolarMeasurement(
                header=_header(nxt * 5.0),
                sensor_id="s1",
                epoch=nxt,
                range=10.0,
                covariance=[1.0, 0.0, 0.0, 1.0],
                detected=True,
            ),
        ),
        ("sim", "stale_epoch", ManoeuvreCommand(platform_id="p1", epoch=0, heading_change=0.1)),
        ("sim", "future_epoch", ManoeuvreCommand(platform_id="p1", epoch=50)),
        ("sim", "unknown_platform", ManoeuvreCommand(platform_id="p9", epoch=epoch)),
        (
            "sim",
            "non_finite",
            ManoeuvreCommand(platform_id="p2", epoch=epoch, heading_change=math.inf),
        ),
        ("sim", "unknown_sensor", SensorSelection(epoch=epoch, selected_sensor_ids=["s9"])),
        ("planner", "bad_covariance", bad_cov),
        ("planner", "unknown_platform", PlatformState(platform_id="p9", epoch=epoch)),
        (
            "planner",
            "non_finite",
            PlatformState(platform_id="p1", epoch=nxt, position=Point(x=math.nan)),
        ),
    ]


class Injector(Node):
    """Publishes every bad message once the track of epoch 2 is out."""

    def __init__(self, **kwargs):
        super().__init__("injector", **kwargs)
        self.sent = []
        self.pubs = {}
        self.create_subscription(TrackEstimate, topics.TRACK, self.on_track, 10)

    def _pub(self, msg):
        kind = type(msg)
        topic = {
            BearingMeasurement: topics.BEARING_MEASUREMENTS,
            PolarMeasurement: topics.POLAR_MEASUREMENTS,
            ManoeuvreCommand: topics.MANOEUVRE_COMMANDS,
            SensorSelection: topics.SENSOR_SELECTION,
            TrackEstimate: topics.TRACK,
            PlatformState: topics.PLATFORM_STATES,
        }[kind]
        if kind not in self.pubs:
            # The graph's per-epoch topics are transient-local: publishers into them offer it.
            self.pubs[kind] = self.create_publisher(kind, topic, qos_for(topic))
        self.pubs[kind].publish(msg)

    def on_track(self, msg):
        if msg.epoch == 2 and not self.sent:
            self.sent = _bad_messages(2)
            for _, _, bad in self.sent:
                self._pub(bad)


@pytest.fixture(scope="module")
def clean_run(tmp_path_factory):
    return run_graph(SCENARIO, run_dir=tmp_path_factory.mktemp("clean"), record=False, plots=False)


def test_bad_input_is_rejected_counted_and_the_run_unchanged(clean_run, tmp_path):
    injectors = []

    def add_injector(graph):
        injectors.append(graph.add(Injector(context=graph.context)))

    result = run_graph(
        SCENARIO, run_dir=tmp_path, record=False, plots=False, before_spin=add_injector
    )
    sent = injectors[0].sent
    assert len(sent) == 15
    expected = {}
    for node, reason, _ in sent:
        expected.setdefault(node, {}).setdefault(reason, 0)
        expected[node][reason] += 1
    for node, reasons in expected.items():
        for reason, n in reasons.items():
            got = result.diagnostics[node].get(f"rejected.{reason}", 0)
            assert got >= n, f"{node} counted {got} rejected.{reason}, expected {n}"
    # The tracker reads platform states too (epochs without measurements) and rejects the same.
    assert result.diagnostics["tracker"].get("rejected.unknown_platform", 0) >= 1
    assert result.diagnostics["tracker"].get("rejected.non_finite", 0) >= 3
    a, b = result.summary.records[0], clean_run.summary.records[0]
    np.testing.assert_array_equal(a.estimate, b.estimate)
    np.testing.assert_array_equal(a.platform_paths, b.platform_paths)
    np.testing.assert_array_equal(a.truth, b.truth)


def test_planner_death_holds_course_then_a_new_planner_resumes(tmp_path):
    state = {"killed": False, "revived": None}

    def chaos(graph):
        sim = next(n for n in graph.nodes if n.get_name() == "sim_node")
        planner = next((n for n in graph.nodes if n.get_name() == "planner_node"), None)
        if not state["killed"] and planner is not None and planner.last_decided >= 2:
            graph.executor.remove_node(planner)
            graph.nodes.remove(planner)
            planner.destroy_node()
            state["killed"] = True
            state["first_held"] = planner.last_decided + 1  # the first epoch nobody commands
        elif state["killed"] and state["revived"] is None and sim.sim.epoch >= 5:
            params = [Parameter("scenario", value=SCENARIO)]
            state["revived"] = graph.add(
                PlannerNode(context=graph.context, parameter_overrides=params)
            )

    result = run_graph(
        SCENARIO,
        run_dir=tmp_path,
        record=False,
        plots=False,
        sim_params={"command_timeout": 0.3},
        during_spin=chaos,
        timeout=60,
    )
    sim = result.diagnostics["sim"]
    assert state["killed"] and state["revived"] is not None
    assert sim["command_timeouts"] >= 2  # both platforms held course at least once
    assert state["revived"].counters.counts["decisions"] >= 1
    # While nobody commanded, the platforms flew straight: the velocity did not change.
    paths = result.summary.records[0].platform_paths
    k = state["first_held"]
    np.testing.assert_allclose(paths[k + 1][:, [1, 3]], paths[k][:, [1, 3]], atol=1e-12)
    assert not np.allclose(paths[k][:, [1, 3]], paths[k - 1][:, [1, 3]])  # it did turn before
    assert len(result.summary.records[0].estimate) == 9  # the run completed, epochs 0..8
