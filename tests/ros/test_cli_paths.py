"""Paths, rates and scenario values that cannot work fail up front: one ``error:`` line, exit
code 2, no traceback, nothing started (no run folder, no bag), and at once.

The cases of issue 26 (--out /dev/null/run, --out under a folder that takes no files,
--json /proc/nope/x.json, which used to traceback after a complete run; play --rate 1e-9,
which waited for ever; ``dt: true`` read as 1.0) and their kin over every command that writes.
Damaged bags through play and retrack: tests/ros/test_bag_damage.py.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import pytest

from activetrack_bringup.cli import main as cli_main

SCENARIO = "tests/ros/data/short_two_sensors.yaml"
pytestmark = pytest.mark.ros


@pytest.fixture(scope="module")
def no_files_folder(tmp_path_factory) -> Path:
    """A folder nothing can be created in: a read-only one, or /sys when running as root
    (root ignores permission bits; sysfs refuses new entries to everyone)."""
    if os.geteuid() == 0:
        return Path("/sys")
    folder = tmp_path_factory.mktemp("locked")
    folder.chmod(0o555)
    return folder


def _scenario_with(tmp_path: Path, name: str, old: str, new: str) -> str:
    text = Path(SCENARIO).read_text()
    assert old in text
    path = tmp_path / f"{name}.yaml"
    path.write_text(text.replace(old, new))
    return str(path)


# (argv with {tmp} / {locked} / {bool_dt} ..., text the error line must hold)
CASES = [
    (["run", SCENARIO, "--out", "/dev/null/run"], "/dev/null is not a folder"),
    (["run", SCENARIO, "--out", "{locked}/run"], "cannot create files in {locked}"),
    (["run", SCENARIO, "--out", "{tmp}/f.txt/run"], "f.txt is not a folder"),
    (["run", SCENARIO, "--out", "{tmp}/r", "--json", "/proc/nope/x.json"], "does not exist"),
    (["run", SCENARIO, "--out", "{tmp}/r", "--json", "{locked}/x.json"], "cannot create files"),
    (["run", SCENARIO, "--out", "{tmp}/r", "--json", "{tmp}"], "is a folder, not a file"),
    (["run", "{bool_dt}", "--out", "{tmp}/r"], "dt: must be a number in [1e-06, 1e+06], not"),
    (["run", "{bool_particles}", "--out", "{tmp}/r"], "tracker.particles: must be an integer"),
    (["batch", "{bool_dt}"], "dt: must be a number"),
    (["batch", SCENARIO, "--json", "/proc/nope/x.json"], "does not exist"),
    (["record", "/dev/null/bag", "--duration", "0.1"], "/dev/null is not a folder"),
    (["record", "{locked}/bag", "--duration", "0.1"], "cannot create files in {locked}"),
    (["play", "{tmp}/none", "--rate", "1e-9"], "--rate: must be a finite number in [0.001"),
    (["play", "{tmp}/none", "--rate", "2e6"], "[0.001, 1e+06]"),
    (["bag", "info", "{tmp}/none", "--json", "/proc/nope/x.json"], "does not exist"),
    (["bag", "retrack", "{tmp}/none", "--scenario", SCENARIO, "--json", "/dev/null/x"], ""),
    (["bag", "recover", "{tmp}/none", "--json", "{locked}/x.json"], "cannot create files"),
    (["track", "{tmp}/d.csv", "--config", SCENARIO, "--out", "/dev/null/t"], "not a folder"),
    (["track", "{tmp}/d.csv", "--config", SCENARIO, "--csv", "/proc/nope/t.csv"], "not exist"),
]


@pytest.mark.parametrize(("argv", "expected"), CASES, ids=[" ".join(c[0])[:70] for c in CASES])
def test_bad_paths_and_values_are_one_error_line_before_anything_starts(
    argv, expected, tmp_path, no_files_folder, capsys
):
    (tmp_path / "f.txt").write_text("a file\n")
    values = {
        "tmp": str(tmp_path),
        "locked": str(no_files_folder),
        "bool_dt": _scenario_with(tmp_path, "dt", "dt: 5.0", "dt: true"),
        "bool_particles": _scenario_with(tmp_path, "n", "particles: 2000", "particles: yes"),
    }
    argv = [a.format(**values) for a in argv]
    start = time.monotonic()
    try:
        rc = cli_main(argv)
    except SystemExit as exc:  # argparse: the usage line, then the error line
        rc = exc.code
    took = time.monotonic() - start
    out, err = capsys.readouterr()
    errors = [line for line in err.splitlines() if "error:" in line]
    assert rc == 2, (out, err)
    assert "Traceback" not in out + err
    assert len(errors) == 1, err
    assert expected.format(**values) in err[err.index("error:") :], err  # its line or the next
    assert not (tmp_path / "r").exists()  # nothing started: no run folder
    assert took < 30.0, f"{took:.1f} s to refuse"  # refused up front (a run takes longer)


def test_checked_output_paths_are_taken_as_given(tmp_path, capsys):
    """The checks leave nothing behind and accept what works: a new nested run folder and a
    --json file that exists already."""
    (tmp_path / "old.json").write_text("{}")
    from activetrack_bringup.cli import build_parser

    args = build_parser().parse_args(
        ["run", SCENARIO, "--out", str(tmp_path / "a" / "b"), "--json", str(tmp_path / "old.json")]
    )
    assert args.out == str(tmp_path / "a" / "b") and args.json == str(tmp_path / "old.json")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["old.json"]  # no probe left


def test_a_summary_written_before_the_graph_started_has_every_run_summary_key(tmp_path):
    """interrupted_before_start writes the keys GraphRun.to_json gives every run."""
    from activetrack_bringup.run_folder import interrupted_before_start
    from activetrack_bringup.runner import GraphRun

    data = interrupted_before_start(tmp_path, 143, 0.5)
    assert set(data) == set(GraphRun(None, tmp_path, None, 0.5, 0.0).to_json())
    assert data["detail"] == "SIGTERM before the graph started"
    assert json.loads((tmp_path / "summary.json").read_text()) == data
