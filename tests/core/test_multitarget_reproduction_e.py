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
# GOSPA [m] of planner, hold_course, random_assignment on runs 0-5, on roughened particle
# tracks with beams pointed at footprints and the planner on the tracks' position traces (its
# file says why). Before roughening and trace_pos: 45.71, 47.13, 58.25 (the planner's run 0 lost
# a target); before, JPDA-EKF with one track per beam: 44.11, 46.76, 49.52.
MEASURED = (35.78, 48.59, 45.66)


@pytest.fixture(scope="module")
def result():
    return reproduce_scene(NAME, RUNS)


def test_each_strategy_keeps_its_figures(result):
    assert_keeps_its_figures(result, MEASURED)


def test_the_planner_is_ahead_of_both_baselines_on_scenario_e(result):
    """(e)'s six runs: the planner's mean GOSPA at least 20 % below both baselines' (the
    issue's margin) and its localisation (beams at footprints update several tracks a look) at
    least 20 % below hold course's (measured: 35.8 against 48.6 and 45.7 m, 26.4 % and 21.6 %;
    1522 against 2040 m^2 per epoch; 100 runs: 24.3 % below the better baseline, planner - hold
    course -13.3 [-18.1, -8.5] m; 200 runs 17.7 %)."""
    (sc,) = result.scenarios
    for baseline in multitarget.BASELINES:
        assert sc.improvement(baseline) > 0.20, baseline
    assert sc.split("planner")[0] < 0.8 * sc.split("hold_course")[0]


def test_the_report_states_the_verdict(result):
    assert_the_report_states_the_verdict(result)
    assert result.manager_note == ""  # no manager on (e)
