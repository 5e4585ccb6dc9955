"""The notebook API: top-level names, run_batch's jobs, tidy tables."""

from __future__ import annotations

import csv
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import activetrack as at

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def scenario():
    sc = at.load_scenario(ROOT / "scenarios" / "default.yaml")
    return sc.model_copy(update={"steps": 8})


@pytest.fixture(scope="module")
def serial(scenario):
    return at.run_batch(scenario, runs=3, jobs=1)


@pytest.mark.parametrize("name, steps", [("default.yaml", 8), ("mt_bearings_crossing.yaml", 10)])
def test_results_do_not_depend_on_jobs(name, steps):
    """One target or three (clutter, beams): the same runs on one process or two."""
    scenario = at.load_scenario(ROOT / "scenarios" / name).model_copy(update={"steps": steps})
    serial, parallel = (at.run_batch(scenario, runs=3, jobs=jobs) for jobs in (1, 2))
    for a, b in zip(serial.records, parallel.records, strict=True):
        for ta, tb in zip(a.tracks, b.tracks, strict=True):
            assert [t.track_id for t in ta.tracks] == [t.track_id for t in tb.tracks]
            for x, y in zip(ta.tracks, tb.tracks, strict=True):
                np.testing.assert_array_equal(x.state, y.state)
                np.testing.assert_array_equal(x.state_cov, y.state_cov)
        np.testing.assert_array_equal(a.platform_paths, b.platform_paths)
        assert [d.beams for d in a.decisions] == [d.beams for d in b.decisions]
    np.testing.assert_array_equal(serial.rmse_t, parallel.rmse_t)
    np.testing.assert_array_equal(serial.bound_t, parallel.bound_t)
    assert serial.run_gospa == parallel.run_gospa and serial.gospa_t == parallel.gospa_t


def test_runs_match_run_once(scenario, serial):
    np.testing.assert_array_equal(
        serial.records[2].track_series()[0], at.run_once(scenario, 2).track_series()[0]
    )


def test_arrays_and_tables_agree(scenario, serial):
    K = scenario.steps
    assert serial.rmse_t.shape == serial.bound_t.shape == (1, K, 2)  # one target
    np.testing.assert_allclose(serial.time, scenario.dt * np.arange(1, K + 1))
    assert serial.time_avg_rmse_x[0] == pytest.approx(serial.rmse_t[0, :, 0].mean(), rel=1e-12)
    rows = serial.table()
    assert [r["epoch"] for r in rows] == list(range(1, K + 1))
    np.testing.assert_array_equal([r["bound_y_m"] for r in rows], serial.bound_t[0, :, 1])
    runs = serial.run_table()
    assert len(runs) == 3 * K
    err = np.array([[r["x_hat_m"] - r["x_m"], r["y_hat_m"] - r["y_m"]] for r in runs])
    rms = np.sqrt((err.reshape(3, K, 2) ** 2).mean(axis=0))
    np.testing.assert_allclose(rms, serial.rmse_t[0], rtol=1e-12)


def test_csv_export(serial, tmp_path):
    path = serial.to_csv(tmp_path / "t.csv")
    with path.open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == serial.steps
    assert float(rows[-1]["rmse_x_m"]) == pytest.approx(serial.rmse_t[0, -1, 0], rel=1e-12)


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_bad_jobs_and_runs_name_the_field(scenario, bad):
    with pytest.raises(ValueError, match="jobs: must be an integer >= 1"):
        at.run_batch(scenario, runs=1, jobs=bad)
    with pytest.raises(ValueError, match="runs: must be an integer >= 1"):
        at.run_batch(scenario, runs=bad)


def test_import_is_lazy_and_complete():
    code = (
        "import sys, activetrack as at\n"
        "assert 'activetrack.closed_loop.batch' not in sys.modules\n"
        "assert set(at.__all__) <= set(dir(at))\n"
        "for name in at.__all__: getattr(at, name)\n"
        "print('ok')"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.strip() == "ok", out.stderr
    with pytest.raises(AttributeError, match="no attribute 'nope'"):
        at.nope  # noqa: B018


def test_cli_batch_jobs_gives_the_same_numbers(tmp_path):
    import json

    from activetrack_bringup.cli import main

    small = tmp_path / "small.yaml"
    text = (ROOT / "scenarios" / "default.yaml").read_text()
    small.write_text(text.replace("steps: 30", "steps: 6"))
    assert "steps: 6" in small.read_text()
    for jobs in ("1", "2"):
        args = ["batch", str(small), "--runs", "3", "--jobs", jobs]
        assert main([*args, "--json", str(tmp_path / f"{jobs}.json")]) == 0
    one, two = (json.loads((tmp_path / f"{j}.json").read_text()) for j in "12")
    timing = {"wall_time_s", "decision_time_s"}
    assert {k for k in one if one[k] != two[k]} <= timing
    assert one["runs"] == 3 and one["steps"] == 6


def test_all_lists_exactly_the_lazy_exports():
    from activetrack import _EXPORTS

    assert set(at.__all__) == {"__version__", *_EXPORTS}
