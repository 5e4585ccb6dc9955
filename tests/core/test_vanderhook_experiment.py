"""Reproduction of Vander Hook et al. (003) Table I, Fig. 5 and the sec. V worked example,
with reduced Monte Carlo sizes (the full run is ``activetrack reproduce vanderhook``)."""

import json
from dataclasses import asdict

import numpy as np
import pytest

from activetrack.scenarios import load_scenario
from activetrack_experiments import scenario_path, vanderhook
from activetrack_experiments.vanderhook_sim import simulate_localisation


@pytest.fixture(scope="module")
def rows():
    return vanderhook.table1(runs=1500, seed=0, jobs=1)


@pytest.fixture(scope="module")
def small():
    return vanderhook.reproduce(runs=100, quick=True, jobs=2)


def test_table1_pinned_numbers(rows):
    # seed 0, 1500 runs: (simulated ratio, our upper bound, two-sided ratio).
    pinned = {
        ("r0_hat", 20.0): (2.931855447945688, 5.560876728003039, 3.3130032766946402),
        ("r0_hat", 200.0): (1.9132480658430437, 3.2258343761538466, 1.9892951007027293),
        ("c_d", 0.25): (1.4885156483032886, 2.5698086299431617, 2.8271873920647606),
    }
    got = {(r.sweep, r.value): r for r in rows}
    for key, (ratio, ub, two) in pinned.items():
        r = got[key]
        assert (r.simulated_ratio, r.upper_bound) == pytest.approx((ratio, ub), rel=1e-9)
        assert r.simulated_ratio_two_sided == pytest.approx(two, rel=1e-9)
    # The base setting appears three times (c_d = 0.1, t_m = 60, beta = 0.1): one batch.
    base = [got[("c_d", 0.1)], got[("t_m", 60.0)], got[("beta", 0.1)]]
    assert len({(r.simulated_ratio, r.upper_bound, r.distance) for r in base}) == 1


def test_reproduce_is_independent_of_jobs(small):
    one = vanderhook.reproduce(runs=100, quick=True, jobs=1)
    assert one.to_json() == small.to_json()
    assert (small.runs, small.seed) == (100, 0)
    assert [f.beta for f in small.failures] == [*vanderhook.QUICK_BETAS, None]
    assert [f.beta for f in small.failures_two_sided] == [*vanderhook.TWO_SIDED_BETAS, None]
    row = small.failures[1]  # beta = 0.1, one-sided, 100 runs
    assert (row.final_wrong_side_rate, row.wrong_side_rate, row.first_wrong_side_rate) == (
        0.25,
        0.39,
        0.18,
    )
    assert row.median_error == pytest.approx(30.799139840003946, rel=1e-9)
    assert row.mean_time == pytest.approx(409.9597654196769, rel=1e-9)
    with pytest.raises(ValueError, match="jobs"):
        vanderhook.reproduce(runs=10, jobs=0)


def test_tables_are_flat_rows_equal_to_the_results(small):
    table = small.table()
    assert len(table) == len(small.table1) == 12
    assert set(table[0]) == {*asdict(small.table1[0]), "deviation"}
    for row, r in zip(table, small.table1, strict=True):
        assert row == {**asdict(r), "deviation": r.deviation}
    failures = small.table("failures")
    assert len(failures) == len(small.failures) + len(small.failures_two_sided) == 7
    assert [f["tail"] for f in failures] == ["one_sided"] * 4 + ["two_sided"] * 3
    for row, f in zip(failures, small.failures + small.failures_two_sided, strict=True):
        assert {k: v for k, v in row.items() if k != "tail"} == asdict(f)
    with pytest.raises(ValueError, match="section"):
        small.table("nope")


def test_worked_example_gives_four_measurements():
    ex = vanderhook.worked_example(runs=200)
    assert ex.n_measurements == 4  # Lemma 4, as the paper computes it
    assert ex.n_schedule == 4
    assert ex.n_simulated == 4.0
    assert ex.final_std < 6.0  # "reduce the one sigma bound to less than 6 meters"
    assert ex.travel_closed_form < 220.0  # "travel less than 220 meters"
    assert ex.ratio_bound < 4.0  # "a competitive ratio of less than about 4"


def test_table1_below_bound_and_within_35_percent_of_paper(rows):
    assert len(rows) == 12
    for r in rows:
        assert r.simulated_ratio < r.upper_bound, (r.sweep, r.value)
        assert abs(r.deviation) < 0.35, (r.sweep, r.value, r.simulated_ratio, r.paper_ratio)


def test_table1_trends_follow_paper(rows):
    def ratios(sweep):
        return [r.simulated_ratio for r in rows if r.sweep == sweep]

    r0, cd, tm, beta = ratios("r0_hat"), ratios("c_d"), ratios("t_m"), ratios("beta")
    assert r0[0] > r0[1] > r0[2]  # r0_hat = 20, 50, 200: decreasing
    assert cd[0] < cd[1] < cd[2]  # c_d = 0.25, 0.1, 0.01: increasing
    assert tm[0] < tm[1] < tm[2]  # t_m = 20, 60, 110: increasing
    assert beta[0] > beta[1] > beta[2]  # beta = 0.1, 0.2, 0.5: decreasing


def test_cautious_ends_on_wrong_side_less_often_than_greedy():
    common = dict(sigma0=60.0, r0_hat=100.0, c_d=0.1, t_m=60.0)
    greedy = simulate_localisation(
        3000, np.random.default_rng(1), strategy="greedy", greedy_range=10.0, **common
    )
    g = greedy.final_wrong_side.mean()
    for beta, tail, margin in (
        (0.1, "one_sided", 0.08),
        (0.1, "two_sided", 0.12),
        (0.01, "two_sided", 0.2),
    ):
        cautious = simulate_localisation(
            3000, np.random.default_rng(1), beta=beta, tail=tail, **common
        )
        assert cautious.final_wrong_side.mean() < g - margin, (beta, tail)
        assert np.median(cautious.final_error) < np.median(greedy.final_error)
    # Fig. 5: more caution, more measurements and smaller final error.
    few = simulate_localisation(1000, np.random.default_rng(2), beta=0.2, **common)
    many = simulate_localisation(1000, np.random.default_rng(2), beta=0.001, **common)
    assert many.n_measurements.mean() > few.n_measurements.mean()
    assert np.median(many.final_error) < np.median(few.final_error)


def test_main_writes_json(tmp_path, capsys):
    path = tmp_path / "vh.json"
    argv = ["--quick", "--runs", "7", "--jobs", "2", "--out", str(tmp_path / "out")]
    assert vanderhook.main([*argv, "--json", str(path)]) == 0
    data = json.loads(path.read_text())
    assert data["runs"] == 400  # --quick sets the runs
    assert (tmp_path / "out" / "results.json").read_text() == path.read_text()
    assert capsys.readouterr().out.startswith("Worked example (sec. V)")
    assert data["n_measurements"] == 4
    assert len(data["table1"]) == 12
    assert {"sweep", "value", "simulated_ratio", "upper_bound"} <= set(data["table1"][0])
    assert (tmp_path / "out" / "fig5_beta.png").stat().st_size > 0


def test_scenario_file_loads():
    s = load_scenario(scenario_path("vanderhook_cautious"))
    assert s.planner.search == "cautious"
    assert s.target.motion.model == "ncv" and s.target.motion.q == 0.0
    assert s.platforms[0].controllable
    assert s.platforms[0].sensors[0].kind == "ambiguous_bearing"
