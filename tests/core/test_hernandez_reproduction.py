"""Hernandez (2004) Table 1 reproduction with reduced Monte Carlo settings.

The bounds are deterministic given the planner's samples, so one run of the planning suffices;
the particle filter part runs a few reduced runs only to check the plumbing and the RMSE vs
bound relation loosely (docs/hernandez.md has the full 100-run table).
"""

import json

import numpy as np
import pytest

from activetrack.experiments import hernandez

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def doc(tmp_path_factory):
    out = tmp_path_factory.mktemp("hernandez")
    argv = [
        "--runs",
        "4",
        "--particles",
        "2000",
        "--jobs",
        "1",
        "--grid-size",
        "21",
        "--out",
        str(out / "figs"),
        "--json",
        str(out / "h.json"),
    ]
    assert hernandez.main(argv) == 0
    data = json.loads((out / "h.json").read_text())
    data["_out"] = str(out)
    return data


def cases(doc):
    return {(c["sensors"], c["horizon"]): c for c in doc["cases"]}


def test_json_layout_and_figures(doc):
    c = cases(doc)
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
    assert c[(1, 1)]["evaluations_per_decision"] <= 34
    assert c[(1, 2)]["evaluations_per_decision"] == 34 + 34 * 34  # two-step DP, 1 sensor
    comp = doc["search_comparison"]
    assert comp["grid"]["evaluations_per_decision"] == 21 * 21
    assert len(doc["figures"]) == 3
    for f in doc["figures"]:
        with open(f, "rb") as fh:
            assert fh.read(8) == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(("n", "tol"), [(1, 0.25), (2, 0.15), (3, 0.15)])
def test_table1_bounds_within_tolerance_of_the_paper(doc, n, tol):
    c = cases(doc)
    for R in (1, 2):
        paper = hernandez.PAPER_TABLE1[(n, R)]
        assert abs(c[(n, R)]["bound_x"] / paper[0] - 1) <= tol, (n, R, "x")
        assert abs(c[(n, R)]["bound_y"] / paper[1] - 1) <= tol, (n, R, "y")


def test_two_step_not_worse_and_more_sensors_not_worse(doc):
    c = cases(doc)
    total = {k: v["bound_x"] + v["bound_y"] for k, v in c.items()}
    for n in (1, 2, 3):
        assert total[(n, 2)] <= 1.02 * total[(n, 1)]
    for R in (1, 2):
        assert total[(2, R)] <= total[(1, R)]
        assert total[(3, R)] <= total[(2, R)]


def test_pf_rmse_reported_and_not_far_below_the_bound(doc):
    # 4 runs of 2000 particles: a loose check (the 100-run numbers are in docs/hernandez.md).
    for entry in doc["cases"]:
        for axis in ("x", "y"):
            rmse, bound = entry[f"pf_rmse_{axis}"], entry[f"bound_{axis}"]
            assert np.isfinite(rmse)
            assert rmse >= 0.6 * bound


def test_bad_arguments_exit_with_usage_error():
    with pytest.raises(SystemExit):
        hernandez.main(["--sensors", "4"])
    with pytest.raises(SystemExit):
        hernandez.main(["--runs", "-1"])
