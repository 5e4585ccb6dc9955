"""``activetrack reproduce multitarget`` on (c), ``mt_appear_disappear``: seeded runs per
strategy on common random numbers (multitarget_scenes.py), keeping their figures (MEASURED)."""

from __future__ import annotations

import pytest
from multitarget_scenes import (
    assert_keeps_its_figures,
    assert_the_report_states_the_verdict,
    reproduce_scene,
)

from activetrack_experiments import multitarget

NAME = "mt_appear_disappear"
# Two runs: (c)'s figures and margin are all its tests assert (six cost 82 CPU-s, two 27).
RUNS = 2
# GOSPA [m] of planner, hold_course and random_assignment on runs 0-1, the tracker reporting the
# confirmed tracks by expected GOSPA (tracker.tracks.report: gospa; its file says why). Before,
# reporting every confirmed track: 79.09, 84.54, 91.62; on runs 0-5 with the prior's track ended
# at existence 0.02: 66.93, 71.29, 98.08; with the default prior threshold: 73.96, 76.11,
# 97.42; before existence terminated tracks from priors 73.29, 78.09, 92.80; on the one
# generator before common random numbers 67.65, 87.11, 86.69.
MEASURED = (73.41, 77.97, 80.61)


@pytest.fixture(scope="module")
def result():
    return reproduce_scene(NAME, RUNS)


def test_each_strategy_keeps_its_figures(result):
    assert_keeps_its_figures(result, MEASURED)


def test_the_planner_is_ahead_of_both_baselines_on_scenario_c(result):
    """(c)'s two runs: the planner's mean GOSPA at least 5 % below both baselines' (the issue's
    margin; measured 73.4 against 78.0 and 80.6 m, 5.8 % and 8.9 %; 100 runs: 5.7 % below hold
    course, -3.5 [-6.0, -1.1] m)."""
    (sc,) = result.scenarios
    for baseline in multitarget.BASELINES:
        assert sc.improvement(baseline) > 0.05, baseline


def test_the_report_states_the_verdict(result):
    assert_the_report_states_the_verdict(result)
    assert result.manager_note == ""  # no manager on (c)
