"""Lockstep that recovers (docs/robustness.md, "Lockstep"): one of the graph's own messages
delayed or lost (activetrack_ros.inject, not a writer from outside) costs at most the input of
its epoch, and every later epoch proceeds without a timeout.

The short scenario's messages per epoch: a truth array, two platform states, two scans (from
epoch 1), a track array, two commands and a plan report (to epoch 7); the n-th message of a
topic below is epoch 3's (its first platform's, where there are two)."""

import time
from dataclasses import replace

import numpy as np
import pytest
from parity import assert_same_run
from rclpy.parameter import Parameter

from activetrack.filters.jpda import NetOversize
from activetrack_bringup.runner import RunIncomplete, epoch_timeouts, run_graph
from activetrack_ros import graph as topics
from activetrack_ros.inject import ENV, parse
from activetrack_ros.node_base import Rejected, unaccounted
from sim_node import sim_node
from tracker_node import tracker_node

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
EPOCH = 3  # the epoch whose message is delayed or lost
NTH = {
    topics.GROUND_TRUTH: 4,  # epochs 0, 1, 2, 3
    topics.PLATFORM_STATES: 7,  # p1 and p2 of 0, 1, 2, then p1 of 3
    topics.SCANS: 5,  # s1 and s2 of 1, 2, then s1 of 3
    topics.TRACKS: 4,
    topics.MANOEUVRE_COMMANDS: 7,
    topics.PLAN_REPORT: 4,
}
# Small timeouts, so that a case whose timeout must fire costs seconds; long enough that in a
# clean epoch on a loaded machine none fires (a decision here takes well under 0.5 s).
COMMAND_TIMEOUT = 2.0
EPOCH_TIMEOUT = 4.0
# Past the command timeout, within the epoch timeout: the sim must know that the epoch is
# still in the graph. A command late past the command timeout is lost: 2 s past it, so that
# a stalled executor cannot swap the two.
DELAY = {topics.MANOEUVRE_COMMANDS: 4.0}
DEFAULT_DELAY = 2.5
pytestmark = pytest.mark.ros


def _run(tmp_path, monkeypatch, faults: str = "", sim_params=None, **options):
    """The run; one that a timeout decided an epoch of is returned too (it ends
    lockstep_timeouts, exit code 1: :func:`_assert_status`); any other failure raises."""
    monkeypatch.setenv(ENV, faults)
    options.setdefault("timeout", 120)
    try:
        return run_graph(
            SCENARIO,
            **options,
            run_dir=tmp_path,
            record=False,
            plots=False,
            sim_params={"command_timeout": COMMAND_TIMEOUT, **(sim_params or {})},
            tracker_params={"epoch_timeout": EPOCH_TIMEOUT},
        )
    except RunIncomplete as exc:
        if exc.result.status != "lockstep_timeouts":
            raise
        assert exc.exit_code == 1
        return exc.result


def _assert_status(run) -> None:
    """Every epoch run; a run where a timeout decided an epoch does not say complete."""
    assert run.complete
    if run.timeouts:
        assert run.status == "lockstep_timeouts", run.status
        assert run.detail.startswith(f"lockstep lost at epoch(s) {min(run.timeouts)} (")
    else:
        assert run.status == "complete", (run.status, run.detail)


@pytest.fixture(scope="module")
def clean(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        run = _run(tmp_path_factory.mktemp("clean"), mp)
    assert run.timeouts == {}
    return run


def _record(run):
    return run.summary.records[0]


def _same_until(a, b, k: int) -> None:
    """The runs agree on everything the graph did before epoch k's lost input."""
    assert np.array_equal(a.truth[: k + 1], b.truth[: k + 1])
    assert np.array_equal(a.platform_paths[: k + 1], b.platform_paths[: k + 1])
    assert [t.epoch for t in a.tracks] == [t.epoch for t in b.tracks]


def _injected(run, at: str, what: str, topic: str) -> int:
    return run.diagnostics[at].get(f"injected.{what}.{topic}", 0)


def test_the_hook_parses_and_refuses_malformed_items():
    faults = parse("publish:activetrack/scans#5=delay:2.5, tracker:activetrack/tracks#3=drop")
    assert [(f.at, f.topic, f.n, f.delay) for f in faults] == [
        ("publish", "activetrack/scans", 5, 2.5),
        ("tracker", "activetrack/tracks", 3, None),
    ]
    for bad in ("publish:activetrack/scans#0=drop", "scans#1=drop", "p:t#1=delay:1e9", "p:t#1=x"):
        with pytest.raises(ValueError, match="ACTIVETRACK_INJECT"):
            parse(bad)


def test_the_summary_gathers_the_timeouts_by_epoch():
    diagnostics = {
        "sim": {"timeout.3.held_course": 2, "command_timeouts": 2, "timeout.x.y": 1},
        "tracker": {"timeout.3.missing_scans": 1, "timeout.12.closed_incomplete": 1},
    }
    assert epoch_timeouts(diagnostics) == {
        3: {"sim": {"held_course": 2}, "tracker": {"missing_scans": 1}},
        12: {"tracker": {"closed_incomplete": 1}},
    }


@pytest.mark.parametrize("topic", list(NTH))
def test_a_late_message_costs_nothing_but_time(topic, clean, tmp_path, monkeypatch):
    """Every reader gets epoch 3's message 2.5 s late, past the sim's command timeout: the
    sim waits while the epoch is still in the graph (the tracker has not answered it) and the
    run is the clean one, without a timeout; only a command itself late past the command
    timeout is lost (hold course at epoch 3) and the epochs after it proceed as usual."""
    start = time.monotonic()
    delay = DELAY.get(topic, DEFAULT_DELAY)
    run = _run(tmp_path, monkeypatch, f"publish:{topic}#{NTH[topic]}=delay:{delay}")
    _assert_status(run)
    writer = {topics.TRACKS: "tracker", topics.MANOEUVRE_COMMANDS: "planner"}
    writer |= {topics.PLAN_REPORT: "planner"}
    assert _injected(run, writer.get(topic, "sim"), "delay", topic) == 1
    if topic == topics.MANOEUVRE_COMMANDS:
        assert run.timeouts == {EPOCH: {"sim": {"held_course": 1}}}
        _same_until(_record(run), _record(clean), EPOCH)
        # (it comes 2 s after the hold, when the run has often finished: refused as stale)
        assert run.diagnostics["sim"].get("rejected.future_epoch", 0) == 0
    else:
        assert run.timeouts == {}
        assert_same_run(_given_up_report(run, clean, topic), _record(clean))
    assert time.monotonic() - start < clean.wall_time_s + delay + 15


def _given_up_report(run, clean, topic: str):
    """The run's record; without the plan report of EPOCH (only the evaluator reads it, and
    it gives up a report report_grace after the sim finished, often before a late one comes),
    its record takes the clean run's report there."""
    record = _record(run)
    decision = record.decisions[EPOCH]
    if topic != topics.PLAN_REPORT or decision.report is not None:
        return record
    assert run.diagnostics["evaluator"].get("received.PlanReport", 0) == 7  # all but EPOCH's
    report = _record(clean).decisions[EPOCH].report
    decisions = list(record.decisions)
    decisions[EPOCH] = replace(decision, report=report)
    return replace(record, decisions=decisions)


# One reader loses one message (its writer's history keeps it): what the epoch loses.
LOST = {
    # the tracker closes epoch 3 without the scan after its epoch timeout
    ("tracker", topics.SCANS): {"tracker": {"closed_incomplete": 1, "missing_scans": 1}},
    # ... or without the state (the scan is used where it says it was: the same update)
    ("tracker", topics.PLATFORM_STATES): {"tracker": {"closed_incomplete": 1, "missing_states": 1}},
    # the planner cannot decide epoch 3: both platforms hold course
    ("planner", topics.PLATFORM_STATES): {"sim": {"held_course": 2}},
    ("planner", topics.TRACKS): {"sim": {"held_course": 2}},
    # the commands say the tracker answered: nothing lost
    ("sim", topics.TRACKS): None,
    ("sim", topics.MANOEUVRE_COMMANDS): {"sim": {"held_course": 1}},
}
SAME_RESULT = {("tracker", topics.PLATFORM_STATES), ("sim", topics.TRACKS)}


@pytest.mark.parametrize(("reader", "topic"), list(LOST), ids=lambda v: v.rsplit("/", 1)[-1])
def test_a_lost_message_costs_one_epoch_at_most(reader, topic, clean, tmp_path, monkeypatch):
    start = time.monotonic()
    run = _run(tmp_path, monkeypatch, f"{reader}:{topic}#{NTH[topic]}=drop")
    _assert_status(run)
    assert _injected(run, reader, "drop", topic) == 1
    want = LOST[reader, topic]
    assert run.timeouts == ({} if want is None else {EPOCH: want})
    if (reader, topic) in SAME_RESULT:
        assert_same_run(_record(run), _record(clean))
    else:
        _same_until(_record(run), _record(clean), EPOCH)
    # One timeout at most, not one an epoch.
    assert time.monotonic() - start < clean.wall_time_s + EPOCH_TIMEOUT + 15


def test_a_tracker_behind_the_sim_catches_up_from_its_buffer(clean, tmp_path, monkeypatch):
    """The sim gives up on the tracker before the tracker gives up on epoch 3's lost scan
    (tracks_timeout 1 s < epoch_timeout 4 s): epoch 4 arrives while the tracker still waits;
    it is buffered, not refused, and once complete it closes epoch 3 with what came. Only
    epoch 3 held course; epoch 4 on proceeds without a timeout."""
    fault = f"tracker:{topics.SCANS}#{NTH[topics.SCANS]}=drop"
    run = _run(tmp_path, monkeypatch, fault, sim_params={"tracks_timeout": 1.0})
    _assert_status(run)
    assert run.timeouts == {
        EPOCH: {
            "sim": {"no_track_array": 1, "held_course": 2},
            "tracker": {"closed_incomplete": 1, "missing_scans": 1},
        }
    }
    tracker = run.diagnostics["tracker"]
    assert tracker.get("rejected.future_epoch", 0) == 0 and tracker["updates"] == 8
    _same_until(_record(run), _record(clean), EPOCH)
    assert run.wall_time_s < clean.wall_time_s + EPOCH_TIMEOUT  # the epoch timeout never ran


def test_the_tracker_buffer_is_bounded(graph, monkeypatch):
    """Messages of at most BUFFER_EPOCHS epochs ahead are kept (here 2, for the 8 epochs of
    the short run); a later one is refused, counted as future_epoch."""
    monkeypatch.setattr(tracker_node, "BUFFER_EPOCHS", 2)
    params = [Parameter("scenario", value=SCENARIO)]
    tracker = graph.add(tracker_node.TrackerNode(context=graph.context, parameter_overrides=params))
    assert tracker.mode == "lockstep"
    tracker.open_epoch(2, "scan")
    with pytest.raises(Rejected, match="future_epoch"):
        tracker.open_epoch(3, "scan")
    assert list(tracker.epochs) == [2]


def test_an_oversize_cluster_is_counted_and_reported_and_the_tracker_goes_on(graph, monkeypatch):
    """oversize_cluster: error: an epoch whose step meets a JPDA cluster too large for exact
    association is closed untracked, counted, logged and reported on /diagnostics (no error
    escapes the callback); the next epoch is tracked, and pruning done under ``prune`` is
    counted in the node's counters as the tracker counts it."""
    params = [Parameter("scenario", value=SCENARIO)]
    node = graph.add(tracker_node.TrackerNode(context=graph.context, parameter_overrides=params))
    step, reports = node.core.step, []
    monkeypatch.setattr(node, "publish_diagnostics", lambda hdr, text: reports.append(text))

    def oversize(k, t, scans):
        raise NetOversize("set tracker.tracks.oversize_cluster: prune", tracks=347,
                          measurements=347, pairs=1626, max_edges=5_000_000)  # fmt: skip

    def pruned(k, t, scans):
        node.core.pruning.clusters += 2
        node.core.pruning.pairs += 40
        return step(k, t, scans)

    for k, fake in ((1, oversize), (2, pruned), (3, pruned)):
        monkeypatch.setattr(node.core, "step", fake)
        node.open_epoch(k, "scan")
        node.guarded(node.process, k, True)
    counts = node.counters.counts
    assert counts["association.oversize_epochs"] == 1 and node.last_epoch == 3
    assert counts["updates"] == 2 and node.counters.total("errors.") == 0
    assert (counts["association.pruned_clusters"], counts["association.dropped_pairs"]) == (4, 80)
    assert "epoch 1 not tracked: a JPDA cluster of 347 tracks" in reports[0]
    assert len(reports) == 3 and not node.epochs


@pytest.mark.slow
def test_node_processes_wait_for_a_late_scan_too(clean, tmp_path, monkeypatch, localhost_discovery):
    """With one process per node (each reads the hook from the environment): a scan 2.5 s
    late, past the command timeout, changes nothing; no timeout fires."""
    late = f"publish:{topics.SCANS}#{NTH[topics.SCANS]}=delay:{DEFAULT_DELAY}"
    run = _run(tmp_path, monkeypatch, late, processes=True)
    _assert_status(run)
    assert run.diagnostics["sim"].get(f"injected.delay.{topics.SCANS}") == 1
    assert run.timeouts == {}
    assert_same_run(_record(run), _record(clean))


@pytest.mark.parametrize("expect_tracker", [False, True])
def test_a_sim_that_expects_a_tracker_waits_for_one_not_yet_discovered(graph, expect_tracker):
    """No track array writer on the graph (a tracker process still starting): a sim alone holds
    course after command_timeout; one that expects a tracker (the graph runner's) waits up to
    tracks_timeout for its track array."""
    params = [
        Parameter("scenario", value=SCENARIO),
        Parameter("command_timeout", value=0.5),
        Parameter("tracks_timeout", value=1.5),
        Parameter("expect_tracker", value=expect_tracker),
    ]
    sim = graph.add(sim_node.SimNode(context=graph.context, parameter_overrides=params))
    started = sim.epoch_started  # epoch 0, published at start-up
    held = lambda: sim.counters.counts.get("timeout.0.no_track_array", 0) == 1  # noqa: E731
    assert graph.spin_until(held, timeout=5.0, step=0.005)
    waited = time.monotonic() - started
    assert sim.count_publishers(topics.TRACKS) == 0
    if expect_tracker:
        assert 1.5 <= waited < 2.5
    else:
        assert 0.5 <= waited < 1.4


def _all_counted(run) -> None:
    assert {node: unaccounted(c) for node, c in run.diagnostics.items()} == dict.fromkeys(
        run.diagnostics, 0
    )


# The evaluator's reader loses one message (the n-th of its topic, as NTH; tracks#9: epoch 8's,
# the last, which no later message reveals): it is fetched again from the writer's history.
REFETCHED = {
    (topics.SCANS, 5): "Scan",  # one of two of an epoch
    (topics.TRACKS, 9): "TrackArray",  # found by the last fetch, report_grace after the end
    (topics.MANOEUVRE_COMMANDS, 7): "ManoeuvreCommand",  # a decision, not given up
}


@pytest.mark.parametrize(("topic", "n"), list(REFETCHED), ids=lambda v: str(v).rsplit("/")[-1])
def test_a_message_lost_to_the_evaluator_is_fetched_again(topic, n, clean, tmp_path, monkeypatch):
    run = _run(tmp_path, monkeypatch, f"activetrack_evaluator:{topic}#{n}=drop", timeout=20)
    _assert_status(run)
    assert run.timeouts == {}
    evaluator = run.diagnostics["evaluator"]
    assert _injected(run, "evaluator", "drop", topic) == 1
    name = REFETCHED[topic, n]
    assert evaluator[f"accepted.refetched.{name}"] == 1
    assert evaluator.get(f"refetch_unfilled.{name}", 0) == 0
    assert_same_run(_record(run), _record(clean))
    _all_counted(run)
    assert run.wall_time_s < clean.wall_time_s + 5  # not the run's timeout


# A message never sent (dropped at its writer): what the graph's timeouts decide at epoch 3,
# what the evaluator gives up, and the last epoch its summary covers. Not parametrised:
# platform states (the tracker closes the epoch without it, as for a scan, and the planner
# cannot decide it, as for a track array; docs/robustness.md has its cost).
NEVER_SENT = {
    # only the evaluator reads truth: nothing in the graph waits
    topics.GROUND_TRUTH: ({}, "truth missing at epochs 3", EPOCH - 1),
    # the tracker closes epoch 3 after its epoch timeout; the run is scored without the scan
    topics.SCANS: (
        {"tracker": {"closed_incomplete": 1, "missing_scans": 1}},
        "scans missing at epochs 3",
        8,
    ),
    # the sim waits tracks_timeout (here 2 s) for the tracker, the planner has nothing to plan
    topics.TRACKS: (
        {"sim": {"no_track_array": 1, "held_course": 2}},
        "track array missing at epochs 3",
        EPOCH - 1,
    ),
}
TRACKS_TIMEOUT = 2.0
# (only there: shorter than the tracker's epoch timeout, it would make a lost scan cost the
# sim's wait too, test_a_tracker_behind_the_sim_catches_up_from_its_buffer)
SIM_PARAMS = {topics.TRACKS: {"tracks_timeout": TRACKS_TIMEOUT}}
LOST_GRACE = 1.0  # the report grace: given up at the last fetch


@pytest.mark.parametrize("topic", list(NEVER_SENT), ids=lambda v: v.rsplit("/", 1)[-1])
def test_a_message_never_sent_ends_the_run_promptly_not_complete(
    topic, clean, tmp_path, monkeypatch
):
    """No history holds it: once the sim and the tracker finished and lost_grace passed, the
    evaluator gives it up and the run ends messages_lost (rc 1), naming it, with the summary
    of the epochs it can score; no epoch after the affected one timed out."""
    start = time.monotonic()
    with pytest.raises(RunIncomplete) as info:
        _run(
            tmp_path, monkeypatch, f"publish:{topic}#{NTH[topic]}=drop",
            sim_params=SIM_PARAMS.get(topic), lost_grace=LOST_GRACE, timeout=30,
        )  # fmt: skip
    wall = time.monotonic() - start
    run, (timeouts, missing, last) = info.value.result, NEVER_SENT[topic]
    assert info.value.exit_code == 1 and not run.complete and run.status == "messages_lost"
    covered = "all epochs" if last == 8 else f"epochs 0-{last} of 8"
    assert run.detail.startswith(missing) and run.detail.endswith(f"summary covers {covered}")
    assert run.timeouts == ({EPOCH: timeouts} if timeouts else {})
    assert run.epochs_completed == last and run.summary.records[0].truth.shape[0] == last + 1
    record, clean_record = _record(run), _record(clean)
    if last == 8:
        _same_until(record, clean_record, EPOCH)
    else:
        assert np.array_equal(record.truth, clean_record.truth[: last + 1])
        assert np.array_equal(record.platform_paths, clean_record.platform_paths[: last + 1])
    name = {topics.GROUND_TRUTH: "GroundTruthArray", topics.SCANS: "Scan"}.get(topic, "TrackArray")
    assert run.diagnostics["evaluator"][f"refetch_unfilled.{name}"] >= 1  # looked for it
    _all_counted(run)
    cost = {topics.SCANS: EPOCH_TIMEOUT, topics.TRACKS: TRACKS_TIMEOUT + COMMAND_TIMEOUT}
    assert wall < clean.wall_time_s + cost.get(topic, 0) + LOST_GRACE + 10
