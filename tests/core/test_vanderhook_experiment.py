"""Reproduction of Vander Hook et al. (003) Table I, Fig. 5 and the sec. V worked example,
with reduced Monte Carlo sizes (the full run is ``activetrack reproduce vanderhook``)."""

import json
from pathlib import Path

import numpy as np
import pytest

from activetrack.experiments import vanderhook
from activetrack.experiments.vanderhook_sim import simulate_localisation
from activetrack.scenarios import load_scenario


@pytest.fixture(scope="module")
def rows():
    return vanderhook.table1(runs=1500, seed=0)


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


def test_main_writes_json(tmp_path):
    path = tmp_path / "vh.json"
    assert vanderhook.main(["--quick", "--out", str(tmp_path / "out"), "--json", str(path)]) == 0
    data = json.loads(path.read_text())
    assert data["n_measurements"] == 4
    assert len(data["table1"]) == 12
    assert {"sweep", "value", "simulated_ratio", "upper_bound"} <= set(data["table1"][0])
    assert (tmp_path / "out" / "fig5_beta.png").stat().st_size > 0


def test_scenario_file_loads():
    s = load_scenario(Path(__file__).parents[2] / "scenarios" / "vanderhook_cautious.yaml")
    assert s.planner.search == "cautious"
    assert s.target.motion.model == "ncv" and s.target.motion.q == 0.0
    assert s.platforms[0].controllable
    assert s.platforms[0].sensors[0].kind == "ambiguous_bearing"
