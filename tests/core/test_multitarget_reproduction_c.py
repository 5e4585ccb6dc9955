"""``activetrack reproduce multitarget`` on (c), ``mt_appear_disappear``: seeded runs per
strategy on common random numbers (multitarget_scenes.py), keeping their figures (MEASURED)."""

from __future__ import annotations

import pytest
from multitarget_scenes import (
    assert_keeps_its_figures,
    assert_the_report_states_the_verdict,
    reproduce_scene,
)

NAME = "mt_appear_disappear"
# Two runs: (c)'s figures are all its test asserts (six cost 82 CPU-s, two 27).
RUNS = 2
# GOSPA [m] of planner, hold_course, random_assignment on runs 0-1, the prior's track ended at
# existence 0.02 (its file says why; measured, runs 0-5: 66.93, 71.29, 98.08). On runs 0-5
# before, with the default prior threshold: 73.96, 76.11, 97.42; before existence terminated
# tracks from priors 73.29, 78.09, 92.80; on the one generator before common random numbers
# 67.65, 87.11, 86.69.
MEASURED = (79.09, 84.54, 91.62)


@pytest.fixture(scope="module")
def result():
    return reproduce_scene(NAME, RUNS)


def test_each_strategy_keeps_its_figures(result):
    assert_keeps_its_figures(result, MEASURED)


def test_the_report_states_the_verdict(result):
    assert_the_report_states_the_verdict(result)
    assert result.manager_note == ""  # no manager on (c)
