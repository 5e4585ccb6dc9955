"""``activetrack reproduce multitarget`` on (e), ``mt_mixed_platforms``: seeded runs per
strategy on common random numbers (multitarget_scenes.py), keeping their figures (MEASURED)
and what they show."""

from __future__ import annotations

import pytest
from multitarget_scenes import (
    assert_keeps_its_figures,
    assert_the_report_states_the_verdict,
    reproduce_scene,
)

from activetrack_experiments import multitarget

NAME = "mt_mixed_platforms"
RUNS = 6
# GOSPA [m] of planner, hold_course, random_assignment on runs 0-5, on particle tracks with
# beams pointed at footprints (its file says why). Before, JPDA-EKF with one track per beam:
# 44.11, 46.76, 49.52; before missed looks aged with the prediction's spread (the planner's run
# 0 now loses a target): 37.26 for the planner.
MEASURED = (45.71, 47.13, 58.25)


@pytest.fixture(scope="module")
def result():
    return reproduce_scene(NAME, RUNS)


def test_each_strategy_keeps_its_figures(result):
    assert_keeps_its_figures(result, MEASURED)


def test_the_planner_is_ahead_of_both_baselines_on_scenario_e(result):
    """(e)'s six runs: the planner's mean GOSPA below both baselines' and its localisation
    (beams at footprints update several tracks a look) at least 10 % below hold course's
    (measured: 45.7 against 47.1 and 58.3 m, 1619 against 1922 m^2 per epoch; the planner's
    run 0 loses a target, 87.4 m; 20 runs: 21.1 % below the better baseline, planner - hold
    course -11.1 [-20.4, -1.8] m)."""
    (sc,) = result.scenarios
    for baseline in multitarget.BASELINES:
        assert sc.improvement(baseline) > 0.02, baseline
    assert sc.split("planner")[0] < 0.9 * sc.split("hold_course")[0]


def test_the_report_states_the_verdict(result):
    assert_the_report_states_the_verdict(result)
    assert result.manager_note == ""  # no manager on (e)
