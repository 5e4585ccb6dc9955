"""A flood from another process (2,000 msg/s of random messages on five of the graph's topics)
during a lockstep run: every message is accounted for, the graph's own messages all get
through, and the run equals the clean one bit for bit."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from parity import assert_same_run

from activetrack_bringup.runner import run_graph
from activetrack_ros import graph as topics
from activetrack_ros.node_base import unaccounted

# Three-step planning with 2 sensors: ~8 s in one process, longer than the 2 s flood.
SCENARIO = "scenarios/hernandez_2sensor_three.yaml"
ADVERSARY = Path(__file__).parents[1] / "tools" / "adversary.py"  # run in its own process
pytestmark = [pytest.mark.ros, pytest.mark.slow]

# Flooded topic -> the graph's readers of it in a run without a bag.
READERS = {
    topics.SCANS: ("tracker", "evaluator"),
    topics.PLATFORM_STATES: ("tracker", "planner", "evaluator"),
    topics.TRACKS: ("sim", "planner", "evaluator"),
    topics.MANOEUVRE_COMMANDS: ("sim", "evaluator"),
    topics.DIAGNOSTICS: ("evaluator",),
}
TYPE_OF = {
    topics.SCANS: "Scan",
    topics.PLATFORM_STATES: "PlatformState",
    topics.TRACKS: "TrackArray",
    topics.MANOEUVRE_COMMANDS: "ManoeuvreCommand",
    topics.DIAGNOSTICS: "DiagnosticArray",
}


def test_a_flood_from_another_process_is_counted_and_changes_nothing(tmp_path, localhost_discovery):
    # A three-step decision takes seconds on a busy machine, more under the flood (dropping
    # each message costs every reader time): the sim waits for each command, however late,
    # rather than hold course after its default 5 s and change the run.
    patient = {"command_timeout": 120.0}
    clean = run_graph(
        SCENARIO, run_dir=tmp_path / "clean", record=False, plots=False, sim_params=patient
    )
    env = {k: v for k, v in os.environ.items() if k != "_ROS_WHEELS_BOOTSTRAP_COMPLETE"}
    readers = [f"{t}={len(r)}" for t, r in READERS.items()]
    command = [sys.executable, str(ADVERSARY), "--rate", "2000"]
    flooder = subprocess.Popen(
        [*command, "--duration", "2", *readers],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )

    def start_under_flood(graph):  # a flood still going as the run ends is not all counted
        while (line := flooder.stdout.readline()) and line.strip() != "flooding":
            pass

    try:
        result = run_graph(
            SCENARIO, run_dir=tmp_path / "flooded", record=False, plots=False,
            sim_params=patient, before_spin=start_under_flood,
        )  # fmt: skip
        sent = json.loads(flooder.communicate(timeout=60)[0].strip().splitlines()[-1])
    finally:
        flooder.kill()
    assert sum(sent.values()) >= 3900  # 2 s at 2,000 msg/s
    for topic, nodes in READERS.items():
        name = TYPE_OF[topic]
        for node in nodes:
            counts = result.diagnostics[node]
            counted = counts.get(f"foreign.{name}", 0) + counts.get(f"dropped.{name}", 0)
            assert counted == sent[name], f"{node}: {counted} of {sent[name]} {name} counted"
            assert counts.get(f"dropped.{name}", 0) == 0  # nothing lost at all: flow control
    for node, counts in result.diagnostics.items():
        assert not [k for k in counts if k.startswith("errors.")]
        assert unaccounted(counts) == 0, (node, counts)  # each message in exactly one counter
    assert_same_run(result.summary.records[0], clean.summary.records[0])
