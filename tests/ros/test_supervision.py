"""Supervised node processes and signals: deaths are noticed at once, a restartable planner
comes back, Ctrl-C and SIGTERM stop a run within 2 s with a summary, and no node process
outlives the runner, however it dies."""

import json
import os
import shutil
import signal
import subprocess
import sys
import time
import uuid
from pathlib import Path

import pytest
import yaml

from activetrack_bringup.runner import RunIncomplete, run_graph

SHORT = "tests/ros/data/short_two_sensors.yaml"
# Three-step planning, ~1 s per decision (about 30 s a run): time to interrupt it at any epoch.
LONG = "scenarios/hernandez_3sensor_three.yaml"
pytestmark = [pytest.mark.ros, pytest.mark.slow, pytest.mark.usefixtures("localhost_discovery")]


# docs/robustness.md: a death is "noticed at the next executor step (under 2 s)". An executor
# step takes up to 64 queued samples per reader, and on a loaded host the first poll after a
# kill came 1.007 s after it once (a 1-s bound, stricter than the promise, failed in CI).
NOTICE_S = 2.0


def _kill_at(node_name: str, epoch: int, log: dict):
    """A during_spin hook: SIGKILL one node process once the evaluator has that epoch."""

    def hook(graph):
        if "killed_at" in log or epoch not in graph.evaluator.tracks:
            return
        supervisor = graph.supervisor
        proc = next(n for n in supervisor.nodes if n.name == node_name).popen
        proc.kill()
        log["killed_at"] = time.monotonic()
        poll = supervisor.poll

        def timed_poll():  # when the runner's poll first sees the death
            try:
                poll()
            except Exception:
                log.setdefault("noticed_at", time.monotonic())
                raise
            if proc.poll() is not None and proc is not _popen(supervisor, node_name):
                log.setdefault("noticed_at", time.monotonic())  # restarted: a new process

        supervisor.poll = timed_poll

    return hook


def _popen(supervisor, node_name: str):
    return next(n for n in supervisor.nodes if n.name == node_name).popen


def _processes(scenario, run_dir, **kwargs):
    """A run with one OS process per node, no bag, no plots."""
    return run_graph(
        scenario, processes=True, run_dir=run_dir, record=False, plots=False, timeout=120, **kwargs
    )


def test_a_killed_tracker_fails_the_run_at_once_and_says_which(tmp_path):
    log = {}
    with pytest.raises(RunIncomplete) as info:
        _processes(SHORT, tmp_path, during_spin=_kill_at("tracker_node", 0, log))
    returned = time.monotonic() - log["killed_at"]
    noticed = log["noticed_at"] - log["killed_at"]
    result = info.value.result
    assert info.value.exit_code == 1 and result.status == "node_died"
    assert "tracker_node was killed by SIGKILL" in result.detail
    # Noticed at the runner's next poll; then the other nodes are stopped and the summary of
    # the completed epochs written.
    assert noticed < NOTICE_S, f"noticed {noticed:.2f} s after the kill"
    assert returned < 10.0, f"run_graph returned {returned:.2f} s after the kill"
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["complete"] is False and summary["status"] == "node_died"
    # What the evaluator held covers the epochs completed (DDS discovery decides how many).
    assert summary["epochs_completed"] == result.epochs_completed <= 8


def test_a_killed_planner_is_restarted_and_the_run_completes(tmp_path):
    log = {}
    # Free mode at 10x real time (0.5 s an epoch): the planner dies with most of the run still
    # ahead, however late this process reads the graph's messages (in lockstep the other
    # processes may finish all 8 epochs in a fraction of a second).
    result = _processes(
        SHORT,
        tmp_path,
        mode="free",
        sim_params={"rate": 10.0},
        during_spin=_kill_at("planner_node", 1, log),
    )
    assert "killed_at" in log and "noticed_at" in log, log
    assert log["noticed_at"] - log["killed_at"] < NOTICE_S
    assert result.complete and result.restarts == {"planner_node": 1}
    assert len(result.summary.records[0].tracks) == 9


def test_a_scenario_can_make_the_planner_essential(tmp_path):
    essential = tmp_path / "essential.yaml"
    essential.write_text(Path(SHORT).read_text() + "graph: {restartable: []}\n")
    log = {}
    with pytest.raises(RunIncomplete) as info:
        _processes(essential, tmp_path / "run", during_spin=_kill_at("planner_node", 1, log))
    assert "planner_node was killed by SIGKILL" in info.value.result.detail


def test_a_node_that_fails_at_start_up_is_reported_at_once(tmp_path):
    start = time.monotonic()
    with pytest.raises(RunIncomplete) as info:
        # tick 0 is refused by the sim: it exits 2 before it publishes anything.
        _processes(SHORT, tmp_path, sim_params={"tick": 0.0})
    assert "sim_node exited with status 2" in info.value.result.detail
    assert time.monotonic() - start < 15


# --- the command line under signals ---------------------------------------------------------


def _unique_scenario(tmp_path: Path) -> Path:
    """A copy with a unique file name: the node processes' command lines carry it."""
    path = tmp_path / f"sup_{uuid.uuid4().hex[:10]}.yaml"
    shutil.copy(LONG, path)
    return path


def _node_processes(marker: str) -> list[str]:
    """PIDs of node processes (not the runner) whose command line names the scenario."""
    pattern = f"_node --ros-args .*{marker}"
    out = subprocess.run(["pgrep", "-f", pattern], capture_output=True, text=True)
    return out.stdout.split()


def _start(tmp_path: Path, *extra: str):
    scenario = _unique_scenario(tmp_path)
    out = tmp_path / "run"
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    cmd = [str(Path(sys.executable).parent / "activetrack"), "run", str(scenario), "--no-plots"]
    proc = subprocess.Popen(
        [*cmd, "--out", str(out), *extra],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        # As a terminal's foreground job (a shell starts background jobs with SIGINT ignored;
        # the command line takes it all the same: interrupts.raising).
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    return proc, out, scenario.name


def _on_disk(bag: Path, topic: str = "/activetrack/tracks") -> int:
    """Messages of ``topic`` the recorder has flushed, from the metadata.yaml it keeps
    current."""
    try:
        meta = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    except (OSError, yaml.YAMLError, KeyError, TypeError):
        return 0
    counts = {
        t["topic_metadata"]["name"]: t["message_count"]
        for t in meta.get("topics_with_message_count") or []
    }
    return counts.get(topic, 0)


def _wait_until_running(proc, out: Path, timeout: float = 60):
    """Until the run is a few epochs in for the runner too: three track arrays and three truths
    recorded and flushed (between processes the runner's participant may hear of the sim one
    discovery announcement, about 3 s, after the tracker does; until then it has no epoch)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        assert proc.poll() is None, proc.communicate()[0]
        bag = out / "bag"
        if _on_disk(bag) >= 3 and _on_disk(bag, "/activetrack/ground_truth") >= 3:
            return
        time.sleep(0.05)
    raise AssertionError("the run did not start")


def _bag_info(bag: Path) -> subprocess.CompletedProcess:
    exe = str(Path(sys.executable).parent / "activetrack")
    return subprocess.run([exe, "bag", "info", str(bag)], capture_output=True, text=True)


@pytest.mark.parametrize(
    ("sig", "code", "processes"),
    [(signal.SIGINT, 130, False), (signal.SIGTERM, 143, True)],
    ids=["ctrl-c-one-process", "sigterm-processes"],
)
def test_a_signal_stops_the_run_within_two_seconds_with_a_summary(sig, code, processes, tmp_path):
    proc, out, marker = _start(tmp_path, *(["--processes"] if processes else []))
    _wait_until_running(proc, out)
    sent = time.monotonic()
    proc.send_signal(sig)
    output = proc.communicate(timeout=30)[0]
    stopped = time.monotonic() - sent
    assert proc.returncode == code, output
    assert stopped < 2.0, f"took {stopped:.2f} s"
    assert "Traceback" not in output
    time.sleep(0.2)
    assert _node_processes(marker) == []
    summary = json.loads((out / "summary.json").read_text())
    assert summary["complete"] is False and summary["status"] == "interrupted"
    assert 1 <= summary["epochs_completed"] < 30
    info = _bag_info(out / "bag")
    assert info.returncode == 0, info.stdout + info.stderr


def test_a_killed_runner_leaves_no_node_behind_and_a_recoverable_bag(tmp_path):
    proc, out, marker = _start(tmp_path, "--processes")
    _wait_until_running(proc, out)
    assert len(_node_processes(marker)) == 3
    proc.kill()
    proc.communicate(timeout=30)
    deadline = time.monotonic() + 2.0
    while _node_processes(marker) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _node_processes(marker) == [], "node processes outlived the runner"
    exe = str(Path(sys.executable).parent / "activetrack")
    info = _bag_info(out / "bag")
    if info.returncode != 0:  # the writer died mid-chunk: rebuild the index first
        recover = subprocess.run(
            [exe, "bag", "recover", str(out / "bag")], capture_output=True, text=True
        )
        assert recover.returncode == 0, recover.stdout + recover.stderr
        info = _bag_info(out / "bag")
    assert info.returncode == 0, info.stdout + info.stderr
    assert "/activetrack/tracks" in info.stdout
