"""Hernandez (2004) Table 1 reproduction with reduced Monte Carlo settings.

The bounds are deterministic given the planner's samples, so one run of the planning suffices;
the particle filter part runs a few reduced runs only to check the plumbing and the RMSE vs
bound relation loosely (docs/hernandez.md has the full 100-run table).
"""

import json
import re

import numpy as np
import pytest

from activetrack_experiments import hernandez

pytestmark = pytest.mark.slow

# reproduce(runs=4, particles=2000) at the scenarios' seed 1: (bound_x, bound_y, pf_rmse_x,
# pf_rmse_y), the numbers `activetrack reproduce hernandez --runs 4 --particles 2000` prints.
EXPECTED = {
    (1, 1): (12.455546, 10.926384, 16.257133, 12.716575),
    (1, 2): (9.611989, 11.111807, 13.978628, 14.962204),
    (2, 1): (6.836664, 6.828512, 10.257007, 5.516817),
    (2, 2): (6.502500, 6.486711, 11.632410, 7.859810),
    (3, 1): (5.897930, 5.980316, 17.251658, 6.631024),
    (3, 2): (4.678382, 4.634959, 10.890486, 7.636394),
}
TIMING = re.compile(r"time_s$")


@pytest.fixture(scope="module")
def res():
    return hernandez.reproduce(runs=4, particles=2000, jobs=1, grid_size=21)


def without_timing(doc):
    """The document without wall-time entries (they differ between two runs)."""
    if isinstance(doc, dict):
        return {k: without_timing(v) for k, v in doc.items() if not TIMING.search(k)}
    if isinstance(doc, list):
        return [without_timing(v) for v in doc]
    return doc


def test_table1_numbers_for_the_seed(res):
    got = {c.key: (c.bound_x, c.bound_y, c.pf_rmse_x, c.pf_rmse_y) for c in res.cases}
    assert sorted(got) == sorted(EXPECTED)
    for key, expected in EXPECTED.items():
        np.testing.assert_allclose(got[key], expected, rtol=1e-6, err_msg=str(key))
    imp = res.improvements()
    np.testing.assert_allclose(imp[1], [22.829646, -1.697024, 14.015412, -17.659070], rtol=1e-5)


def test_json_layout(res):
    doc = json.loads(json.dumps(res.to_json()))
    c = {(e["sensors"], e["horizon"]): e for e in doc["cases"]}
    assert sorted(c) == [(n, R) for n in (1, 2, 3) for R in (1, 2)]
    for entry in c.values():
        for key in (
            "sensors",
            "horizon",
            "search",
            "bound_x",
            "bound_y",
            "pf_rmse_x",
            "pf_rmse_y",
            "evaluations_per_decision",
            "decision_time_s",
        ):
            assert key in entry
        assert entry["search"] == "quadrant"
        assert len(entry["bound_x_by_epoch"]) == 30
        assert len(entry["pf_rmse_y_by_epoch"]) == 30
        assert (entry["pf_runs"], entry["pf_particles"]) == (4, 2000)
    assert c[(1, 1)]["evaluations_per_decision"] <= 34
    assert c[(1, 2)]["evaluations_per_decision"] == 34 + 34 * 34  # two-step DP, 1 sensor
    assert sorted(doc["table2_improvement_percent"]) == ["1", "2", "3"]
    comp = doc["search_comparison"]
    assert comp["grid"]["evaluations_per_decision"] == 21 * 21
    assert comp["quadrant"]["bound_x"] == c[(1, 1)]["bound_x"]
    assert len(comp["grid_path"]) == 31


def test_table_has_one_row_per_case_with_the_arrays_values(res):
    rows = res.table()
    assert len(rows) == 6
    columns = set(rows[0])
    assert {"sensors", "horizon", "bound_x", "pf_rmse_y", "paper_bound_x", "pf_runs"} <= columns
    for row, case in zip(rows, res.cases, strict=True):
        assert set(row) == columns
        assert all(not isinstance(v, (list, dict, np.ndarray)) for v in row.values())
        assert (row["sensors"], row["horizon"]) == case.key
        assert row["bound_x"] == case.plan.bounds[:, 0].mean()
        assert row["bound_y"] == case.plan.bounds[:, 1].mean()
        assert row["pf_rmse_x"] == case.rmse[:, 0].mean()
        assert row["pf_rmse_y"] == case.rmse[:, 1].mean()
        assert row["paper_bound_y"] == hernandez.PAPER_TABLE1[case.key][1]


def test_figures_and_text(res, tmp_path):
    files = hernandez.save_figures(res, tmp_path / "figs")
    assert [f.name for f in files] == [
        "fig2_1sensor_quadrant_vs_grid.png",
        "fig3_2sensors_single_vs_two.png",
        "bounds_and_rmse_all_cases.png",
    ]
    for f in files:
        assert f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    # Drawn on two worker processes: the same files, byte for byte.
    two = hernandez.save_figures(res, tmp_path / "figs2", jobs=2)
    assert [f.read_bytes() for f in two] == [f.read_bytes() for f in files]
    text = hernandez.format_results(res)
    assert "x-coordinate       12.5 (16.3)          9.6 (14.0) " in text
    assert "  grid 21x21       bound (" in text
    assert res.prior_samples.shape == (31, 1000, 4)


@pytest.mark.parametrize(("n", "tol"), [(1, 0.25), (2, 0.15), (3, 0.15)])
def test_table1_bounds_within_tolerance_of_the_paper(res, n, tol):
    for R in (1, 2):
        paper = hernandez.PAPER_TABLE1[(n, R)]
        c = res.case(n, R)
        assert abs(c.bound_x / paper[0] - 1) <= tol, (n, R, "x")
        assert abs(c.bound_y / paper[1] - 1) <= tol, (n, R, "y")


def test_two_step_not_worse_and_more_sensors_not_worse(res):
    total = {c.key: c.bound_x + c.bound_y for c in res.cases}
    for n in (1, 2, 3):
        assert total[(n, 2)] <= 1.02 * total[(n, 1)]
    for R in (1, 2):
        assert total[(2, R)] <= total[(1, R)]
        assert total[(3, R)] <= total[(2, R)]


def test_pf_rmse_reported_and_not_far_below_the_bound(res):
    # 4 runs of 2000 particles: a loose check (the 100-run numbers are in docs/hernandez.md).
    for c in res.cases:
        for rmse, bound in ((c.pf_rmse_x, c.bound_x), (c.pf_rmse_y, c.bound_y)):
            assert np.isfinite(rmse)
            assert rmse >= 0.6 * bound


SMALL = dict(sensors=[1], horizons=[1], runs=3, particles=300, grid_size=5)


def test_jobs_do_not_change_the_results():
    one = hernandez.reproduce(**SMALL, jobs=1)
    two = hernandez.reproduce(**SMALL, jobs=2)
    assert np.array_equal(one.cases[0].rmse, two.cases[0].rmse)
    assert without_timing(one.to_json()) == without_timing(two.to_json())
    np.testing.assert_allclose(
        (one.cases[0].pf_rmse_x, one.cases[0].pf_rmse_y), (30.974711, 15.750705), rtol=1e-6
    )


def test_comparison_plans_its_own_quadrant_when_the_cases_do_not():
    """Without the 1-sensor single-step case among the cases (two-step only), the plan map
    also plans the comparison's quadrant: the same plan as planning it alone."""
    res = hernandez.reproduce(sensors=[1], horizons=[2], runs=0, grid_size=5)
    assert [c.key for c in res.cases] == [(1, 2)]
    sdir = hernandez.find_scenarios_dir(None, "hernandez_*.yaml")
    reference = hernandez.load_scenario(hernandez.scenario_path("hernandez_1sensor_single", sdir))
    alone = hernandez.plan_case(reference, search="quadrant")
    assert res.comparison is not None and res.comparison.quadrant.horizon == 1
    np.testing.assert_array_equal(res.comparison.quadrant.paths, alone.paths)
    np.testing.assert_array_equal(res.comparison.grid.paths[0], alone.paths[0])
    assert res.comparison.grid.search == "grid"


def test_comparison_with_another_search_still_compares_the_quadrant():
    """With the cases planned by another search (--search sector), the comparison plans its
    own quadrant instead of labelling the cases' plan as one."""
    res = hernandez.reproduce(sensors=[1], horizons=[1], runs=0, grid_size=5, search="sector")
    assert res.cases[0].plan.search == "sector"
    assert res.comparison is not None and res.comparison.quadrant.search == "quadrant"


def test_plan_map_runs_heaviest_first():
    sdir = hernandez.find_scenarios_dir(None, "hernandez_*.yaml")
    tasks = [
        (hernandez.load_scenario(hernandez.scenario_path(hernandez.scenario_name(n, R), sdir)), kw)
        for n, R, kw in ((1, 1, {}), (3, 1, {}), (2, 2, {}), (1, 1, {"search": "grid"}), (3, 2, {}))
    ]
    order = sorted(range(len(tasks)), key=lambda i: hernandez._plan_order(tasks[i]))
    assert order == [4, 2, 3, 1, 0]  # 3s two-step, 2s two-step, the grid, 3s single, 1s single


def test_main_prints_and_writes_the_json_of_reproduce(tmp_path, capsys):
    argv = ["--sensors", "1", "--horizons", "1", "--runs", "3", "--particles", "300"]
    argv += ["--grid-size", "5", "--jobs", "1", "--no-figures", "--json", str(tmp_path / "h.json")]
    assert hernandez.main(argv) == 0
    out, err = capsys.readouterr()
    assert err.startswith("[hernandez] 1 sensor(s), single-step: bound (12.46, 10.93) m, 34 ")
    assert out.startswith("Table 1: RMSE bounds averaged over k = 1..30")
    assert "grid 5x5" in out
    doc = json.loads((tmp_path / "h.json").read_text())
    expected = json.loads(json.dumps(hernandez.reproduce(**SMALL).to_json()))
    assert without_timing(doc) == without_timing(expected)


def test_bad_arguments():
    with pytest.raises(SystemExit):
        hernandez.main(["--sensors", "4"])
    with pytest.raises(SystemExit):
        hernandez.main(["--runs", "-1"])
    for bad in (dict(sensors=[4]), dict(horizons=[3]), dict(runs=-1), dict(jobs=0)):
        with pytest.raises(ValueError):
            hernandez.reproduce(**bad)
    with pytest.raises(ValueError, match="--search grid with --horizons 2"):
        hernandez.reproduce(search="grid")
