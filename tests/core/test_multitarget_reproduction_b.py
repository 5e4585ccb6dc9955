"""``activetrack reproduce multitarget`` on (b), ``mt_radars_beams``: seeded runs per strategy
on common random numbers (multitarget_scenes.py), keeping their figures (MEASURED) and what
they show."""

from __future__ import annotations

import pytest
from multitarget_scenes import (
    assert_keeps_its_figures,
    assert_the_report_states_the_verdict,
    reproduce_scene,
)

NAME = "mt_radars_beams"
RUNS = 6
# GOSPA [m] of planner, hold_course, random_assignment on runs 0-5, with the information
# reduction of the tracker's gate on S (clutter_gate: innovation; holding course's runs 0 and
# 1 each lose a target). Before, one q per sensor of R: 114.58, 86.28, 159.36; before a beam's
# missed looks said less as the track's prediction widened: 110.81, 87.53, 160.71; before
# existence terminated tracks from priors 111.04, 94.89, 165.87; on the one generator before
# common random numbers 136.71, 117.14, 225.70.
MEASURED = (66.01, 107.44, 138.51)


@pytest.fixture(scope="module")
def result():
    return reproduce_scene(NAME, RUNS)


def test_each_strategy_keeps_its_figures(result):
    assert_keeps_its_figures(result, MEASURED)


def test_random_beams_lose_targets_on_scenario_b(result):
    """Five targets, three beams: pointing them at random loses tracks (breaks) that the MRE
    assignment keeps."""
    (sc,) = result.scenarios
    assert sc.improvement("random_assignment") > 0.25  # measured 0.52
    planner, rand = sc.summaries["planner"], sc.summaries["random_assignment"]
    # Runs that lost a target for good (GOSPA above c / 2 = 250 m; measured: random 1 of 6,
    # the planner 0). Breaks need not tell them apart (measured: planner 0, random 0.33 per
    # run; before the gate's q planner 0.50, random 0.33): since a confirmed track from a prior
    # is terminated on existence, a lost target's track ends (a break) instead of staying on
    # as a false track.
    lost = {s: sum(g > 250.0 for g in x.run_gospa) for s, x in (("p", planner), ("r", rand))}
    assert lost["r"] > lost["p"]


def test_the_report_states_the_verdict(result):
    assert_the_report_states_the_verdict(result)
    assert result.manager_note == ""  # left out on purpose (stonesoup=False): no note
