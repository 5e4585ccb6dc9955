"""The graph on a busy domain: writers outside it change nothing and are all counted; the
graph's own failures stop the run at once instead of stalling it; a dying planner is survived.
"""

import numpy as np
import pytest
from adversary import CATEGORIES, READERS, ForeignNode, uncounted
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from parity import assert_same_run
from rclpy.parameter import Parameter
from strategies import message

from activetrack.scenarios import load_scenario
from activetrack_bringup.runner import RunIncomplete, run_graph
from activetrack_ros.node_base import unaccounted
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

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
DT = load_scenario(SCENARIO).dt
pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def clean_run(tmp_path_factory):
    return run_graph(SCENARIO, run_dir=tmp_path_factory.mktemp("clean"), record=False, plots=False)


def assert_same_graph_run(a, b):
    """Bit for bit: truth, platform paths, scans, tracks and every decision (parity)."""
    assert_same_run(a.summary.records[0], b.summary.records[0])


def assert_every_message_counted(run, clean, foreign):
    """Each reader in the graph received every message the foreign node sent on its topics
    (none lost uncounted: DDS reported no loss either), counted exactly the unsigned ones as
    foreign, and raised nothing."""
    checked = 0
    for node, counts in run.diagnostics.items():
        base = clean.diagnostics[node]
        assert not {k: v for k, v in counts.items() if k.startswith(("errors.", "dropped."))}
        assert unaccounted(counts) == 0, (node, counts)
        for type_name in _inputs(node):
            sent = foreign.sent[type_name]
            # The genuine count may differ by a late history delivery; the foreign one may not.
            got = counts.get(f"received.{type_name}", 0) - base.get(f"received.{type_name}", 0)
            assert got >= sent, f"{node} received {got} of {sent} {type_name}"
            unsigned = sent - foreign.sent_signed[type_name]
            assert counts.get(f"foreign.{type_name}", 0) == unsigned, (node, type_name)
            checked += sent
    assert checked > 0
    assert uncounted(run.diagnostics, foreign.sent, foreign.sent_signed) == 0


def _inputs(node: str) -> list[str]:
    return [name for name, readers in READERS.items() if node in readers]


def _run_with(tmp_path, **foreign_kwargs):
    nodes = []

    def add(graph):
        nodes.append(graph.add(ForeignNode(dt=DT, context=graph.context, **foreign_kwargs)))

    # Dropping thousands of foreign messages costs every reader's executor time (a flood is
    # not free, activetrack_ros.trust): on a busy machine an epoch's commands may then come
    # later than the sim's default 5 s timeout, and holding course would change the run.
    result = run_graph(
        SCENARIO,
        run_dir=tmp_path,
        record=False,
        plots=False,
        before_spin=add,
        sim_params={"command_timeout": 120.0},
    )
    return result, nodes[0]


def test_inputs_table_matches_the_nodes(clean_run):
    for node, counts in clean_run.diagnostics.items():
        received = {k.removeprefix("received.") for k in counts if k.startswith("received.")}
        assert received <= set(_inputs(node)), node


def test_outsiders_change_nothing_and_every_message_is_counted(clean_run, tmp_path):
    """Every category of hostile traffic (malformed, plausible forgeries, a posing diagnostics
    status, raw garbage, a flood of random messages) from a writer without the key, plus
    replays of the graph's own messages (valid tags): the run is the clean run bit for bit."""
    floods = {t: 200 for t in (Scan, PlatformState, TrackArray, ManoeuvreCommand)}
    others = (BeamCommand, SensorSelection, PlanReport, GroundTruthArray)
    result, foreign = _run_with(
        tmp_path,
        categories=[c.name for c in CATEGORIES],
        floods={**floods, **dict.fromkeys(others, 50)},
        garbage=10,
        replay=True,
        seed=7,
    )
    assert foreign.fired and sum(foreign.sent.values()) > 1000
    assert foreign.sent_signed["PlatformState"] > 0  # the replays carried genuine tags
    assert_same_graph_run(result, clean_run)
    assert_every_message_counted(result, clean_run, foreign)
    unsigned = foreign.sent - foreign.sent_signed
    assert result.foreign["evaluator"] == sum(unsigned[t] for t in _inputs("evaluator")) > 800
    # Replays are recognised as what they are: history, duplicates, stale epochs.
    ev = result.diagnostics["evaluator"]
    assert ev["rejected.duplicate"] >= foreign.sent_signed["GroundTruthArray"]


def test_plausible_forgeries_alone_change_nothing(clean_run, tmp_path):
    plausible = [c.name for c in CATEGORIES if c.plausible]
    assert len(plausible) >= 7
    result, foreign = _run_with(tmp_path, categories=plausible, at_epoch=3)
    assert sum(foreign.sent.values()) >= len(plausible) + 100  # a stream of 119 is one
    assert_same_graph_run(result, clean_run)
    assert_every_message_counted(result, clean_run, foreign)


def test_a_diverged_filter_stops_the_run_at_once(tmp_path, monkeypatch):
    """The graph's own track turns non-finite at epoch 4: the evaluator refuses it like any
    invalid track array, and the runner reports a graph fault instead of waiting for the
    timeout."""
    from activetrack.tracking import tracker as tracker_module

    real_step = tracker_module.Tracker.step

    def diverging(self, epoch, t, scans):
        tracks = real_step(self, epoch, t, scans)
        if epoch == 4:
            tracks.tracks[0].state[:] = np.nan
        return tracks

    monkeypatch.setattr(tracker_module.Tracker, "step", diverging)
    with pytest.raises(RunIncomplete) as info:
        run_graph(SCENARIO, run_dir=tmp_path, record=False, plots=False, timeout=60)
    result = info.value.result
    assert result.status == "graph_fault" and info.value.exit_code == 1
    assert "TrackArray epoch 4" in result.detail and "non_finite" in result.detail
    assert result.wall_time_s < 10
    assert result.epochs_completed == 3  # the summary covers epochs 0..3
    assert len(result.summary.rmse_x_t[0]) == 3


def test_planner_death_holds_course_then_a_new_planner_resumes(tmp_path):
    key = GraphKey.generate()
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
                PlannerNode(context=graph.context, parameter_overrides=params, graph_key=key)
            )

    with pytest.raises(RunIncomplete) as info:  # every epoch run, but not all in lockstep
        run_graph(
            SCENARIO,
            run_dir=tmp_path,
            record=False,
            plots=False,
            sim_params={"command_timeout": 0.3},
            during_spin=chaos,
            timeout=60,
            graph_key=key,
        )
    result = info.value.result
    assert info.value.exit_code == 1 and result.complete and result.status == "lockstep_timeouts"
    held = {k: v["sim"]["held_course"] for k, v in result.timeouts.items()}
    assert min(held) == state["first_held"] and set(held.values()) == {2}
    assert result.detail.startswith(f"lockstep lost at epoch(s) {state['first_held']} (sim ")
    sim = result.diagnostics["sim"]
    assert state["killed"] and state["revived"] is not None
    assert sim["command_timeouts"] >= 2  # both platforms held course at least once
    assert state["revived"].counters.counts["decisions"] >= 1
    # While nobody commanded, the platforms flew straight: the velocity did not change.
    paths = result.summary.records[0].platform_paths
    k = state["first_held"]
    np.testing.assert_allclose(paths[k + 1][:, [1, 3]], paths[k][:, [1, 3]], atol=1e-12)
    assert not np.allclose(paths[k][:, [1, 3]], paths[k - 1][:, [1, 3]])  # it did turn before
    assert len(result.summary.records[0].tracks) == 9  # the run completed, epochs 0..8


def test_a_planner_without_the_key_is_not_obeyed(tmp_path):
    """A second planner on the domain (another user's, started by hand) has no key: its
    commands are foreign to the sim, and the run equals the clean one."""
    extra = []

    def add(graph):
        params = [Parameter("scenario", value=SCENARIO)]
        extra.append(graph.add(PlannerNode(context=graph.context, parameter_overrides=params)))

    clean = run_graph(SCENARIO, run_dir=tmp_path / "a", record=False, plots=False)
    result = run_graph(SCENARIO, run_dir=tmp_path / "b", record=False, plots=False, before_spin=add)
    assert extra[0].graph_key is None and extra[0].counters.counts["decisions"] >= 1
    assert result.diagnostics["sim"]["foreign.ManoeuvreCommand"] >= 2
    assert_same_graph_run(result, clean)


SIGNED_TYPES = [Scan, PlatformState, TrackArray, ManoeuvreCommand, BeamCommand, SensorSelection]


@settings(
    max_examples=4,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    drawn=st.lists(
        st.sampled_from(SIGNED_TYPES).flatmap(lambda t: message(t).map(lambda m: (t, m))),
        min_size=1,
        max_size=25,
    )
)
def test_property_any_foreign_messages_during_a_run_change_nothing(drawn, clean_run, tmp_path):
    """Property: whatever messages an outsider publishes on the graph's topics during a run
    (hypothesis draws them: any field values, any mix of types), the run is the clean run and
    each of them is counted by each of its readers."""
    run_dir = tmp_path / f"h{len(list(tmp_path.iterdir()))}"
    result, foreign = _run_with(run_dir, messages=drawn)
    assert sum(foreign.sent.values()) == len(drawn)
    assert_same_graph_run(result, clean_run)
    assert_every_message_counted(result, clean_run, foreign)
