"""Until the graph's multi-target nodes exist, a multi-target scenario given to a node or to
``activetrack run`` fails at once with one line that says so (exit 2), never a wrong run of its
first target."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from activetrack_bringup.cli import main as cli_main

ROOT = Path(__file__).resolve().parents[2]
MULTI = ROOT / "scenarios" / "mt_bearings_crossing.yaml"


@pytest.mark.parametrize("node", ["sim_node", "tracker_node", "planner_node"])
def test_a_node_refuses_a_multitarget_scenario(node):
    exe = Path(sys.executable).parent / node
    proc = subprocess.run(
        [str(exe), "--ros-args", "-p", f"scenario:={MULTI}"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert proc.returncode == 2, proc.stderr
    assert "is multi-target (targets:)" in proc.stderr
    assert "activetrack batch" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_run_refuses_a_multitarget_scenario(tmp_path, capsys):
    assert cli_main(["run", str(MULTI), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "is multi-target (targets:)" in err and not (tmp_path / "run").exists()
