"""``activetrack track`` (docs/track-your-data.md): a multi-target run's detections, exported to
CSV and JSON or taken from the run's bag, track with the scenario file and the run index to the
run's own tracks bit for bit; the page's hand-written CSV tracks with GOSPA; bad files are one
``error:`` line and exit code 2; tracker_node, given the tracker configuration, tracks in free
mode what ``activetrack play`` publishes from the bag ``activetrack track`` wrote."""

from __future__ import annotations

import math
import shlex
from pathlib import Path

import numpy as np
import pytest
import yaml
from doc_blocks import ROOT, blocks, file_block
from rclpy.parameter import Parameter

from activetrack.closed_loop.components import scene_sensors
from activetrack.closed_loop.loop import run_once
from activetrack.scenarios import load_scenario, load_tracking
from activetrack.tracking.detections import write_detections
from activetrack.tracking.track_files import read_tracks_json
from activetrack_bringup.bag import BagPlayer, graph_schemas, open_bag
from activetrack_bringup.bag_io import Rosbag2Writer, TopicSpec
from activetrack_bringup.cli import build_parser
from activetrack_bringup.cli import main as cli_main
from activetrack_bringup.retrack import read_run
from activetrack_ros import graph as topics
from activetrack_ros.convert import TrackArrayChecker
from activetrack_ros.graph import GRAPH_TOPICS
from activetrack_ros.node_base import GraphNode
from msgs_defs.msg import TrackArray
from tracker_node.tracker_node import TrackerNode

pytestmark = pytest.mark.ros
PAGE = ROOT / "docs" / "track-your-data.md"
RUN = 3


def cli(capsys, *argv) -> tuple[int, str, str]:
    """The command line: (rc, stdout, stderr); never a traceback, a failure in one ``error:``
    line (an invalid configuration's lines that follow it name its fields, as for scenarios)."""
    try:
        rc = cli_main([str(a) for a in argv])
    except SystemExit as exc:  # argparse's own checks
        rc = exc.code
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    if rc == 2:
        assert err.startswith("error: "), err
        assert all(line.startswith("  ") for line in err.strip().splitlines()[1:]), err
    return rc, out, err


def assert_same(a, b) -> None:
    """Track sets equal bit for bit: ids, status, origin, state, covariances, counts."""
    assert [x.epoch for x in a] == [y.epoch for y in b]
    for x, y in zip(a, b, strict=True):
        assert (x.detections, x.unassociated, x.updates) == (
            y.detections,
            y.unassociated,
            y.updates,
        )
        assert [t.track_id for t in x.tracks] == [t.track_id for t in y.tracks], x.epoch
        for s, t in zip(x.tracks, y.tracks, strict=True):
            assert (s.status, s.origin, s.existence, s.hits, s.misses) == (
                t.status, t.origin, t.existence, t.hits, t.misses
            )  # fmt: skip
            for f in ("state", "state_cov", "mean", "cov"):
                assert np.array_equal(getattr(s, f), getattr(t, f)), (x.epoch, s.track_id, f)


@pytest.fixture(scope="module")
def beams(tmp_path_factory):
    """mt_radars_beams cut to 8 epochs: its file, the batch loop's run and the bag of
    ``activetrack run`` (the graph in lockstep, in one process)."""
    tmp = tmp_path_factory.mktemp("beams")
    data = yaml.safe_load((ROOT / "scenarios" / "mt_radars_beams.yaml").read_text())
    data["steps"] = 8
    path = tmp / "beams.yaml"
    path.write_text(yaml.safe_dump(data))
    record = run_once(load_scenario(path), run=RUN)
    argv = ["run", str(path), "--run", str(RUN), "--out", str(tmp / "graph"), "--no-plots"]
    assert cli_main(argv) == 0
    return path, record, tmp / "graph" / "bag"


def test_a_runs_exported_detections_track_to_its_tracks(beams, tmp_path, capsys):
    path, record, _ = beams
    config = load_tracking(path)
    for suffix in (".csv", ".json"):
        scans = tmp_path / f"scans{suffix}"
        write_detections(scans, [s for epoch in record.scans for s in epoch], scene_sensors(config))
        out = tmp_path / f"out{suffix}"
        rc, text, _ = cli(capsys, "track", scans, "--config", path, "--run", RUN, "--out", out)
        assert rc == 0 and "8 epochs, 24 scans" in text
        assert_same(read_tracks_json(out / "tracks.json"), record.tracks)
        assert sorted(p.name for p in out.iterdir()) == ["bag", "tracks.csv", "tracks.json"]


def test_a_graph_runs_bag_tracks_to_its_recorded_tracks(beams, tmp_path, capsys):
    path, record, bag = beams
    out = tmp_path / "out"
    rc, text, _ = cli(
        capsys,
        "track",
        bag,
        "--config",
        path,
        "--run",
        RUN,
        "--out",
        out,
        "--csv",
        tmp_path / "t.csv",
    )
    assert rc == 0 and "GOSPA" in text  # the run's bag holds its truth
    tracked = read_tracks_json(out / "tracks.json")
    config = load_tracking(path)
    check = TrackArrayChecker(config)
    recorded = [check(m) for m in read_run(bag).messages[topics.TRACKS]]
    assert_same(tracked, recorded)  # the graph's tracker, from the bag
    assert_same(tracked, record.tracks)  # and the batch loop's
    assert (tmp_path / "t.csv").read_text() == (out / "tracks.csv").read_text()
    # GOSPA against the bag's truth, with the scenario's evaluation (c = 500 m).
    gospa = yaml.safe_load((out / "tracks.json").read_text())["gospa"]
    assert gospa["epochs"] == list(range(1, 9)) and 0 < gospa["mean"] < 500.0 * len(
        record.target_ids
    )


@pytest.fixture
def example(tmp_path):
    for name in ("harbour.yaml", "detections.csv", "truth.csv"):
        (tmp_path / name).write_text(file_block(name, PAGE))
    return tmp_path


def test_the_pages_example_runs_as_shown(example, capsys, monkeypatch):
    monkeypatch.chdir(example)
    rc, text, err = cli(
        capsys, "track", "detections.csv", "--config", "harbour.yaml", "--truth", "truth.csv",
        "--out", "runs/harbour",
    )  # fmt: skip
    assert rc == 0 and not err
    page = PAGE.read_text()
    shown = page[page.index("```text\ntracked") + len("```text\n") :].split("```")[0]
    assert text == shown
    gospa = [line.split(",") for line in (example / "runs/harbour/gospa.csv").read_text().split()]
    assert gospa[0] == ["epoch", "gospa", "localisation", "missed", "false"]
    assert float(gospa[1][1]) == pytest.approx(200.0 / math.sqrt(2.0), rel=1e-12)
    rows = (example / "runs/harbour/tracks.csv").read_text().splitlines()
    assert rows[0].startswith("epoch,time,track,status,origin,existence,x,vx,y,vy,P_x_x,P_x_vx,")
    assert len(rows) == 1 + 8  # track 1 at epochs 1..6, the clutter track at 3 and 4
    # The bag it wrote holds the scans and the truth: tracked again, the same tracks and GOSPA.
    rc, text, _ = cli(capsys, "track", "runs/harbour/bag", "--config", "harbour.yaml", "--out", "b")
    assert rc == 0 and text.splitlines()[1:3] == shown.splitlines()[1:3]
    assert (example / "b/tracks.csv").read_text() == "\n".join(rows) + "\n"
    assert (example / "b/gospa.csv").read_text() == (example / "runs/harbour/gospa.csv").read_text()


def test_a_bags_scans_are_found_under_any_namespace(example, capsys):
    """The scans of the page's example, alone in a bag under the namespace /harbour, track as
    the CSV does (no truth in it: no GOSPA)."""
    config = example / "harbour.yaml"
    rc, _, _ = cli(
        capsys, "track", example / "detections.csv", "--config", config, "--out", example / "a"
    )
    assert rc == 0
    with open_bag(example / "a" / "bag") as b:
        scans = [(t, d) for _, t, d in b.messages(["/" + topics.SCANS])]
    msgtype = GRAPH_TOPICS[topics.SCANS]
    name = f"/harbour/{topics.SCANS}"
    writer = Rosbag2Writer(example / "ns", [TopicSpec(name, msgtype, *graph_schemas()[msgtype])])
    for log_time, data in scans:
        writer.write(writer.channel_ids[name], log_time, data)
    writer.close()
    rc, text, _ = cli(capsys, "track", example / "ns", "--config", config, "--out", example / "b")
    assert rc == 0 and "6 epochs, 12 scans, 12 detections" in text and "GOSPA" not in text
    assert (example / "b/tracks.csv").read_text() == (example / "a/tracks.csv").read_text()


def test_the_pages_commands_parse():
    commands = [b for b in blocks(PAGE) if b.against == "the command line"]
    assert len(commands) == 3
    for block in commands:
        for line in block.code.splitlines():
            build_parser().parse_args(shlex.split(line)[1:])


def _edit(example: Path, row: int, column: int, value: str) -> Path:
    lines = (example / "detections.csv").read_text().splitlines()
    cells = lines[row - 1].split(",")
    cells[column] = value
    lines[row - 1] = ",".join(cells)
    (example / "bad.csv").write_text("\n".join(lines) + "\n")
    return example / "bad.csv"


def _drop_sensor_vy(example: Path) -> Path:
    lines = (example / "detections.csv").read_text().splitlines()
    rows = [",".join(c for j, c in enumerate(line.split(",")) if j != 6) for line in lines]
    (example / "bad.csv").write_text("\n".join(rows) + "\n")
    return example / "bad.csv"


def _out_of_order(example: Path) -> Path:
    lines = (example / "detections.csv").read_text().splitlines()
    lines[4], lines[5] = lines[5], lines[4]
    (example / "bad.csv").write_text("\n".join(lines) + "\n")
    return example / "bad.csv"


@pytest.mark.parametrize(
    ("make", "says"),
    [
        (_drop_sensor_vy, "row 1 (the header): missing column 'sensor_vy'"),
        (lambda e: _edit(e, 3, 7, "x"), "row 3, column range: must be a finite number"),
        (lambda e: _edit(e, 3, 2, "radr"), "row 3, column sensor: unknown sensor 'radr'"),
        (lambda e: _edit(e, 3, 1, "2.1"), "row 3, column time: must be epoch x dt = 1 x 2"),
        (lambda e: _edit(e, 2, 7, "5"), "row 2, column range: sensor 'dirfinder' (bearing) me"),
        (_out_of_order, "row 6, column epoch: epochs out of order: 2 after 3 (row 5)"),
    ],
)
def test_a_bad_file_is_one_error_line_and_exit_code_2(example, tmp_path, capsys, make, says):
    bad = make(example)
    rc, out, err = cli(
        capsys, "track", bad, "--config", example / "harbour.yaml", "--out", tmp_path / "o"
    )
    assert rc == 2 and not out and len(err.splitlines()) == 1
    assert err.startswith(f"error: {bad}: {says}")
    assert not (tmp_path / "o").exists()  # nothing written: it failed before tracking


def test_bad_inputs_besides_the_data_are_one_line_too(example, tmp_path, capsys):
    config = example / "harbour.yaml"
    data = example / "detections.csv"
    rc, _, err = cli(
        capsys, "track", example / "none.csv", "--config", config, "--out", tmp_path / "a"
    )
    assert rc == 2 and "no such file" in err
    rc, _, err = cli(
        capsys, "track", example / "harbour.yaml", "--config", config, "--out", tmp_path / "b"
    )
    assert rc == 2 and "must be a .csv or .json file (or a bag)" in err
    rc, _, err = cli(capsys, "track", tmp_path, "--config", config, "--out", tmp_path / "c")
    assert rc == 2 and "no metadata.yaml" in err
    (tmp_path / "d").mkdir()
    (tmp_path / "d" / "x").write_text("")
    rc, _, err = cli(capsys, "track", data, "--config", config, "--out", tmp_path / "d")
    assert rc == 2 and "exists already" in err
    (example / "bad.yaml").write_text(
        config.read_text().replace("motion: {model: ncv, q: 0.1}", "")
    )
    rc, _, err = cli(
        capsys, "track", data, "--config", example / "bad.yaml", "--out", tmp_path / "e"
    )
    assert rc == 2 and "tracker.motion: required in a tracker configuration" in err


class _Tracks(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("track_collector", **kwargs)
        self.arrays: dict[int, TrackArray] = {}
        self.subscribe(TrackArray, topics.TRACKS, lambda m: self.arrays.__setitem__(m.epoch, m))


def test_tracker_node_tracks_the_played_bag_in_free_mode(example, graph, capsys):
    """The node, given the tracker configuration, takes the scans and platform states the
    player publishes from the bag `activetrack track` wrote, and tracks as the command did."""
    out = example / "out"
    rc, _, _ = cli(
        capsys,
        "track",
        example / "detections.csv",
        "--config",
        example / "harbour.yaml",
        "--out",
        out,
    )
    assert rc == 0
    params = [
        Parameter("scenario", value=str(example / "harbour.yaml")),
        Parameter("mode", value="free"),
    ]
    collector = graph.add(_Tracks(context=graph.context))
    tracker = graph.add(TrackerNode(context=graph.context, parameter_overrides=params))
    player = graph.add(
        BagPlayer(out / "bag", [topics.SCANS, topics.PLATFORM_STATES], 50.0, context=graph.context)
    )
    done = graph.spin_until(lambda: (player.play_step(), 6 in collector.arrays)[1], timeout=60.0)
    assert done, (sorted(collector.arrays), dict(tracker.counters.counts))
    counts = tracker.counters.counts
    assert counts["updates"] == 6 and counts["detections"] == 12 and not counts["incomplete_epochs"]
    assert not any(k.startswith(("rejected", "errors")) for k in counts), counts
    check = TrackArrayChecker(load_tracking(example / "harbour.yaml"))
    published = [check(collector.arrays[k]) for k in range(7)]
    assert_same(published, read_tracks_json(out / "tracks.json"))
