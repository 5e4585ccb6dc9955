"""``activetrack reproduce multitarget`` on (a), ``mt_bearings_crossing``: six seeded runs per
strategy on common random numbers (multitarget_scenes.py); on the same runs the scene's
particle tracker against the JPDA-EKF.

The multi-target issue's criterion (>= 20 % lower time-averaged GOSPA than both baselines over
100 runs) is judged by the reproduction command (docs/multitarget.md); here the six runs must
keep their figures (MEASURED) and what they show."""

from __future__ import annotations

import pytest
from multitarget_scenes import (
    assert_keeps_its_figures,
    assert_the_report_states_the_verdict,
    reproduce_scene,
)

from activetrack.closed_loop.batch import run_batch
from activetrack.montecarlo.paired import paired_difference
from activetrack.scenarios import load_scenario, with_changes
from activetrack_experiments import multitarget

NAME = "mt_bearings_crossing"
RUNS = 6
# GOSPA [m] of planner, hold_course, random_assignment on runs 0-5 with particle tracks and the
# expected-GOSPA objective over two epochs (its file says why). Before: JPDA-EKF on
# planner.criterion 129.56, 74.35, 107.24 (there the planner lost a target for good in runs 3
# and 4, 203.3 and 309.7 m: a prior's bearings-only track drifted off while the beams served
# the others; particle tracks planning on the expected GOSPA lose none); before existence
# terminated tracks from priors 149.18, 74.35, 114.28; on the one generator before common
# random numbers 57.67, 71.05, 70.75.
MEASURED = (59.31, 66.16, 98.95)


@pytest.fixture(scope="module")
def result():
    return reproduce_scene(NAME, RUNS)


def test_each_strategy_keeps_its_figures(result):
    assert_keeps_its_figures(result, MEASURED)


@pytest.mark.xfail(
    strict=True,
    reason="issue 25: on six runs the planner is ahead of both baselines on (a) (59.3 against "
    "66.2 and 99.0 m) but not by two standard errors; 100 runs resolve it against both "
    "(docs/multitarget.md)",
)
def test_the_planner_beats_both_baselines_on_scenario_a(result):
    (sc,) = result.scenarios
    for baseline in multitarget.BASELINES:
        gain, se = sc.improvement(baseline), sc.improvement_stderr(baseline)
        assert gain > 2.0 * se and gain > 0.2 - se, (baseline, gain, se)
    assert sc.summaries["planner"].breaks == 0.0


def test_the_planner_is_ahead_of_both_baselines_on_scenario_a_and_loses_no_target(result):
    """(a)'s six runs: the planner's mean GOSPA below both baselines' and no target missed at
    any epoch of any run (measured: 59.3 against 66.2 and 99.0 m; random beams miss 0.04 per
    epoch)."""
    (sc,) = result.scenarios
    for baseline in multitarget.BASELINES:
        assert sc.improvement(baseline) > 0.05, baseline
    assert sc.split("planner")[1] == 0.0


def test_the_report_states_the_verdict(result):
    assert_the_report_states_the_verdict(result)
    assert result.manager_note == ""  # no manager on (a)


@pytest.mark.slow
def test_particle_tracker_is_no_worse_than_the_jpda_ekf_on_scene_a(result):
    """Closed loop on (a), the planner, six seeded runs on common random numbers: the particle
    tracker's GOSPA is no worse than the JPDA-EKF's (activetrack.filters.jpda_particle). The
    scene tracks with particles, so its planner's runs are the particle tracker's."""
    base = load_scenario(f"scenarios/{NAME}.yaml")
    assert base.tracker.filter == "pf"
    pf = result.scenarios[0].summaries["planner"]
    ekf = run_batch(with_changes(base, tracker={"filter": "ekf"}), runs=RUNS, keep_records=False)
    d = paired_difference(pf.run_gospa, ekf.run_gospa)
    # Measured: EKF 126.5 m (run 1 458.9 m: a target lost), PF 59.3 m (at most 102.7 m, every
    # target held to the end); PF - EKF -67.2 [-230.8, +96.4] m.
    assert pf.mean_gospa <= ekf.mean_gospa + 5.0
    assert d.mean <= 5.0
    assert pf.mean_gospa < 80.0
    assert max(pf.run_gospa) < 150.0
