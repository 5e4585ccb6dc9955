"""Tracking recorded detections (docs/track-your-data.md): a run's scans written out and read
back track to the run's own tracks bit for bit; the page's hand-written example tracks with
GOSPA against its truth; bad files and configurations fail with one line naming the place."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from doc_blocks import ROOT, file_block

from activetrack.closed_loop.components import build_tracker, scene_sensors
from activetrack.closed_loop.loop import run_once
from activetrack.closed_loop.recorded import track_detections
from activetrack.data import TrackSet
from activetrack.scenarios import (
    ScenarioError,
    load_scenario,
    load_tracking,
    parse_tracking,
    tracking_of,
    with_changes,
)
from activetrack.tracking.detections import (
    DataFileError,
    Detections,
    read_detections,
    read_truth,
    write_detections,
    write_truth,
)
from activetrack.tracking.track_files import read_tracks_json, write_tracks_json

PAGE = ROOT / "docs" / "track-your-data.md"
_SCALARS = (
    "track_id", "status", "origin", "priority", "age", "hits", "misses", "missed_detections",
    "existence", "particle_count",
)  # fmt: skip


def assert_same_track_sets(a: list[TrackSet], b: list[TrackSet]) -> None:
    """Every field of every track set equal, bit for bit (NaN where NaN)."""
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert (x.epoch, x.time, x.filter_kind, x.motion_model, tuple(x.state_names)) == (
            y.epoch, y.time, y.filter_kind, y.motion_model, tuple(y.state_names)
        )  # fmt: skip
        assert (x.updates, x.detections, x.unassociated) == (
            y.updates,
            y.detections,
            y.unassociated,
        )
        assert len(x.tracks) == len(y.tracks), x.epoch
        for s, t in zip(x.tracks, y.tracks, strict=True):
            assert [getattr(s, f) for f in _SCALARS] == [getattr(t, f) for f in _SCALARS]
            for f in ("state", "state_cov", "mean", "cov"):
                assert np.array_equal(getattr(s, f), getattr(t, f)), (x.epoch, s.track_id, f)
            for f in ("nis", "ess"):
                assert np.array_equal(getattr(s, f), getattr(t, f), equal_nan=True)


@pytest.fixture(scope="module")
def beams_run():
    """mt_radars_beams cut to 12 epochs (planned beams, clutter, tracks from detections and
    priors), run 3."""
    scenario = with_changes(load_scenario(ROOT / "scenarios" / "mt_radars_beams.yaml"), steps=12)
    return scenario, run_once(scenario, run=3)


@pytest.mark.parametrize("suffix", [".csv", ".json"])
def test_a_multi_target_runs_scans_track_to_its_tracks_bit_for_bit(beams_run, suffix, tmp_path):
    scenario, record = beams_run
    config = tracking_of(scenario)
    sensors = scene_sensors(config)
    path = tmp_path / f"scans{suffix}"
    write_detections(path, [scan for scans in record.scans for scan in scans], sensors)
    detections = read_detections(path, sensors, config.dt, config.steps)
    assert detections.last_epoch == 12 and detections.count == 36
    result = track_detections(config, detections, run=3)
    # Clutter was there, and tracks from detections next to the priors' tracks.
    assert sum(ts.unassociated for ts in result.track_sets) > 0
    assert any(t.origin == "" for ts in result.track_sets for t in ts.tracks)
    assert_same_track_sets(result.track_sets, record.tracks)


def test_the_scans_of_an_epoch_are_applied_in_the_configurations_sensor_order(beams_run, tmp_path):
    """A file may hold an epoch's scans in any order: read back, they are in sensor order and
    track as the run did; applied in the file's (reversed) order they would not."""
    scenario, record = beams_run
    config = tracking_of(scenario)
    sensors = scene_sensors(config)
    reversed_scans = [scan for scans in record.scans for scan in reversed(scans)]
    write_detections(tmp_path / "r.json", reversed_scans, sensors)
    detections = read_detections(tmp_path / "r.json", sensors, config.dt)
    assert_same_track_sets(track_detections(config, detections, run=3).track_sets, record.tracks)
    as_written = Detections("r", {k: tuple(reversed(detections.at(k))) for k in detections.scans})
    other = track_detections(config, as_written, run=3).track_sets
    with pytest.raises(AssertionError):
        assert_same_track_sets(other, record.tracks)


def test_the_tracks_json_reads_back_bit_for_bit(beams_run, tmp_path):
    scenario, record = beams_run
    write_tracks_json(tmp_path / "tracks.json", record.tracks, config=scenario.name)
    assert_same_track_sets(read_tracks_json(tmp_path / "tracks.json"), record.tracks)


def test_a_single_target_run_tracks_bit_for_bit_from_its_scenario_file(tmp_path):
    """Known association (the papers' one target): the scenario file as the configuration."""
    scenario = with_changes(load_scenario(ROOT / "scenarios" / "default.yaml"), steps=6)
    record = run_once(scenario, run=1)
    path = tmp_path / "default.yaml"
    path.write_text(
        (ROOT / "scenarios" / "default.yaml").read_text().replace("steps: 30", "steps: 6")
    )
    config = load_tracking(path)
    assert config.known_association and config.steps == 6
    sensors = scene_sensors(config)
    write_detections(tmp_path / "d.csv", [s for scans in record.scans for s in scans], sensors)
    detections = read_detections(tmp_path / "d.csv", sensors, config.dt, config.steps)
    assert_same_track_sets(track_detections(config, detections, run=1).track_sets, record.tracks)


def test_the_scenarios_tracker_is_its_configurations():
    scenario = load_scenario(ROOT / "scenarios" / "mt_appear_disappear.yaml")
    config = tracking_of(scenario)
    assert [t.id for t in config.targets] == [t.id for t in scenario.targets if t.birth == 0]
    assert config.targets and len(config.targets) < len(scenario.targets)
    assert not config.known_association and config.tracker.motion == scenario.target.motion
    a = build_tracker(scenario, np.random.default_rng(5)).snapshot()
    b = build_tracker(config, np.random.default_rng(5)).snapshot()
    assert_same_track_sets([a], [b])


# --- the page's example ------------------------------------------------------------------------


@pytest.fixture
def example(tmp_path):
    for name in ("harbour.yaml", "detections.csv", "truth.csv"):
        (tmp_path / name).write_text(file_block(name, PAGE))
    return tmp_path


def test_a_hand_written_csv_tracks_with_gospa_against_its_truth(example):
    config = load_tracking(example / "harbour.yaml")
    assert not config.known_association and config.steps is None
    sensors = scene_sensors(config)
    detections = read_detections(example / "detections.csv", sensors, config.dt)
    assert detections.last_epoch == 6 and detections.count == 12
    assert [s.sensor_id for s in detections.at(3)] == ["dirfinder", "radar"]
    assert detections.at(3)[1].Z.tolist() == [[2246.0, 1.0778], [6120.5, 2.4861]]  # range, bearing
    assert detections.at(2)[0].Z.shape == (0, 1)  # looked, saw nothing
    truth = read_truth(example / "truth.csv", config.dt)
    result = track_detections(config, detections, truth)
    sets = result.track_sets
    # Epoch 1: the radar's detection starts a tentative track at its inverse measurement (the
    # bearing sensor, first in order, had no track to update); no confirmed track, one missed
    # target: GOSPA = (c^2 / 2)^(1/2).
    (first,) = sets[1].tracks
    r, b = 2234.1, 1.0979
    assert first.status == "tentative" and first.origin == ""
    np.testing.assert_allclose(first.mean, [r * math.cos(b), 0.0, r * math.sin(b), 0.0], rtol=1e-12)
    g = result.gospa
    assert g.epochs.tolist() == [1, 2, 3, 4, 5, 6]
    assert g.gospa[0] == pytest.approx(200.0 / math.sqrt(2.0), rel=1e-12)
    assert (g.missed[0], g.false[0]) == (1, 0)
    # From epoch 2 on the confirmed track holds the ship: GOSPA is its position error; the
    # clutter detection at epoch 3 started a tentative track only.
    assert sets[2].confirmed and len(sets[3].tracks) == 2 and len(sets[3].confirmed) == 1
    for k in range(2, 7):
        (track,) = sets[k].confirmed
        error = np.hypot(*(track.mean[[0, 2]] - truth[k].pv[0, [0, 2]]))
        assert g.gospa[k - 1] == pytest.approx(error, rel=1e-12)
        assert error < 10.0  # m, a ship 2.2 km from a 10 m / 2 mrad radar
    assert g.mean == pytest.approx(np.mean(g.gospa))


def test_the_example_in_json_is_the_same(example):
    config = load_tracking(example / "harbour.yaml")
    sensors = scene_sensors(config)
    csv = read_detections(example / "detections.csv", sensors, config.dt)
    write_detections(example / "d.json", [s for k in sorted(csv.scans) for s in csv.at(k)], sensors)
    write_truth(example / "t.json", read_truth(example / "truth.csv", config.dt).values())
    a = track_detections(config, csv, read_truth(example / "truth.csv", config.dt))
    b = track_detections(
        config,
        read_detections(example / "d.json", sensors, config.dt),
        read_truth(example / "t.json", config.dt),
    )
    assert_same_track_sets(a.track_sets, b.track_sets)
    assert np.array_equal(a.gospa.gospa, b.gospa.gospa)


def test_the_pages_json_and_python_blocks_work_as_written(example, monkeypatch, capsys):
    (example / "d.json").write_text(file_block("detections.json", PAGE))
    config = load_tracking(example / "harbour.yaml")
    d = read_detections(example / "d.json", scene_sensors(config), config.dt)
    assert [(s.epoch, s.sensor_id, s.Z.tolist()) for k in (1, 2) for s in d.at(k)] == [
        (1, "dirfinder", [[2.3553]]),
        (2, "dirfinder", []),
    ]
    monkeypatch.chdir(example)
    exec(file_block("track_harbour.py", PAGE), {})
    truth = read_truth("truth.csv", config.dt)
    expected = track_detections(
        config, read_detections("detections.csv", scene_sensors(config), 2.0), truth
    )
    assert capsys.readouterr().out.strip().endswith(repr(expected.gospa.mean))


# --- bad files ---------------------------------------------------------------------------------


def _bad_csv(example: Path, edit) -> str:
    lines = (example / "detections.csv").read_text().splitlines()
    edit(lines)
    (example / "bad.csv").write_text("\n".join(lines) + "\n")
    config = load_tracking(example / "harbour.yaml")
    with pytest.raises(DataFileError) as err:
        read_detections(example / "bad.csv", scene_sensors(config), config.dt)
    message = str(err.value)
    assert "\n" not in message and message.startswith(f"{example / 'bad.csv'}: ")
    return message.split(": ", 1)[1]


def _set(row: int, column: int, value: str):
    def edit(lines):
        cells = lines[row - 1].split(",")
        cells[column] = value
        lines[row - 1] = ",".join(cells)

    return edit


def _drop_column(column: int):
    def edit(lines):
        for i, line in enumerate(lines):
            lines[i] = ",".join(c for j, c in enumerate(line.split(",")) if j != column)

    return edit


def _empty_row(row: int):
    def edit(lines):
        lines[row - 1] = ",".join([*lines[row - 1].split(",")[:7], "", ""])

    return edit


def _extra_column(name: str):
    def edit(lines):
        lines[0] += f",{name}"

    return edit


def _swap_rows(a: int, b: int):
    def edit(lines):
        lines[a - 1], lines[b - 1] = lines[b - 1], lines[a - 1]

    return edit


BAD_ROWS = [  # (the edit, where: row and column, the start of what it says)
    (_drop_column(6), "row 1 (the header)", "missing column 'sensor_vy'"),
    (_set(3, 7, "22x4.1"), "row 3, column range", "must be a finite number in [0, 1e+10], got '22"),
    (
        _set(3, 2, "radr"),
        "row 3, column sensor",
        "unknown sensor 'radr': one of ['dirfinder', 'rad",
    ),
    (_set(3, 1, "2.5"), "row 3, column time", "must be epoch x dt = 1 x 2 = 2 s (to 1e-06 s), got"),
    (
        _set(2, 7, "100.0"),
        "row 2, column range",
        "sensor 'dirfinder' (bearing) measures bearing, n",
    ),
    (_swap_rows(5, 6), "row 6, column epoch", "epochs out of order: 2 after 3 (row 5)"),
    (_set(3, 0, "1.5"), "row 3, column epoch", "must be an integer in [1, 1000000], got '1.5'"),
    (_set(3, 8, ""), "row 3, column bearing", "sensor 'radar' (range_bearing) measures range, bea"),
    (
        _set(3, 8, "4.0"),
        "row 3, column bearing",
        "must be a finite number in [-3.14159, 3.14159], ",
    ),
    (_set(3, 3, "nan"), "row 3, column sensor_x", "must be a finite number"),
    (
        _set(8, 5, "6"),
        "row 8, column sensor_vx",
        "the rows of a scan give the same sensor_vx: 0.0 at",
    ),
    (_empty_row(8), "row 8, column bearing", "an empty row is a scan without detections; the sca"),
    (_swap_rows(7, 6), "row 8, column sensor", "a second scan of 'radar' at epoch 3 (the first at"),
    (_extra_column("target"), "row 1 (the header), column 'target'", "unknown: one of ['epoch', "),
]


@pytest.mark.parametrize(("edit", "where", "says"), BAD_ROWS)
def test_each_bad_value_is_one_line_naming_row_and_column(example, edit, where, says):
    assert _bad_csv(example, edit).startswith(f"{where}: {says}")


def test_bad_json_entries_name_their_place(example):
    config = load_tracking(example / "harbour.yaml")
    sensors = scene_sensors(config)
    path = example / "d.json"
    path.write_text(
        '{"scans": [{"epoch": 1, "time": 2.0, "sensor": "radar", "sensor_x": 0, "sensor_y": 0, '
        '"sensor_vx": 0, "sensor_vy": 0, "detections": [{"range": 10.0, "bearing": true}]}]}'
    )
    with pytest.raises(DataFileError, match=r"scans\[0\]\.detections\[0\]\.bearing: must be a"):
        read_detections(path, sensors, config.dt)
    path.write_text('{"scans": [], "extra": 1}')
    with pytest.raises(DataFileError, match="unknown key 'extra'"):
        read_detections(path, sensors, config.dt)


def test_truth_rows_are_checked(example):
    (example / "t.csv").write_text("epoch,target,x,y,vx,vy\n1,a,0,0,0,0\n1,a,1,0,0,0\n")
    with pytest.raises(DataFileError, match=r"row 3, column target: target 'a' at epoch 1 twice"):
        read_truth(example / "t.csv", 2.0)
    config = load_tracking(example / "harbour.yaml")
    detections = read_detections(example / "detections.csv", scene_sensors(config), config.dt)
    (example / "t.csv").write_text("epoch,target,x,y,vx,vy\n7,a,0,0,0,0\n")
    with pytest.raises(
        DataFileError, match="the truth holds epoch 7, the detections end at epoch 6"
    ):
        track_detections(config, detections, read_truth(example / "t.csv", 2.0))


def test_known_association_refuses_two_detections_in_a_scan_before_tracking(example):
    config = load_tracking(example / "harbour.yaml").model_copy(update={"association": "known"})
    detections = read_detections(example / "detections.csv", scene_sensors(config), config.dt)
    with pytest.raises(
        DataFileError, match=r"row 7: the scan of 'radar' at epoch 3 has 2 detections"
    ):
        track_detections(config, detections)


# --- the configuration ---------------------------------------------------------------------------

_PRIOR = {"mean": [100.0, 0.0, 100.0, 0.0], "var": [1e4, 1.0, 1e4, 1.0]}
_CONFIG = {
    "name": "c",
    "dt": 1.0,
    "platforms": [{"id": "p", "sensors": [{"id": "s", "kind": "bearing", "sigma": 0.01}]}],
    "tracker": {"filter": "ekf", "motion": {"model": "ncv", "q": 1.0}},
    "targets": [{"id": "t", "prior": _PRIOR}],
}


def _problems(**changes) -> str:
    with pytest.raises(ScenarioError) as err:
        parse_tracking({**_CONFIG, **changes}, "c.yaml")
    return str(err.value)


def test_a_tracker_configuration_names_its_bad_fields():
    assert parse_tracking(_CONFIG).known_association  # one target, no clutter
    assert "tracker.motion: required in a tracker configuration" in _problems(
        tracker={"filter": "ekf"}
    )
    assert "tracker.filter: must be one of" in _problems(
        tracker={**_CONFIG["tracker"], "filter": "kf"}
    )
    bad_prior = [{"id": "t", "prior": {"mean": [1.0, 2.0], "var": [1.0, 1.0]}}]
    assert "targets.0.prior.mean: must have 4 entries" in _problems(targets=bad_prior)
    assert "targets: without targets every track starts from detections" in _problems(targets=[])
    assert "targets: association 'known' tracks exactly one target" in _problems(
        targets=[], association="known"
    )
    circular = {
        "filter": "ekf",
        "motion": {"model": "circular", "sigma_omega": 0.1, "sigma_v": 1.0},
    }
    prior = [{"id": "t", "prior": {"mean": [0.0, 1.0, 1.0, 0.0, 1.0], "var": [1.0] * 5}}]
    assert "tracker.motion.model: must be a model of the pv state" in _problems(
        tracker=circular, targets=prior, association="jpda"
    )
    assert "steps" not in _CONFIG  # a file with steps is read as a scenario


def test_a_file_with_steps_is_read_as_a_scenario(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("name: c\ndt: 1.0\nsteps: 5\nplatforms: []\n")
    with pytest.raises(ScenarioError, match=r"\(a scenario: it gives steps\): invalid scenario"):
        load_tracking(path)
