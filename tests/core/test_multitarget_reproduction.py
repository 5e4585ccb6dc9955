"""``activetrack reproduce multitarget`` on the three scenarios, six seeded runs per strategy.

The multi-target issue's criterion (>= 20 % lower time-averaged GOSPA than both baselines over
100 runs) is judged by the reproduction command (docs/multitarget.md has the 100-run figures: on
the one loop (a) misses it, -1.2 % and 8.3 %). Here the same six seeded runs of each strategy
must keep their figures (measured values in MEASURED), so that a change that moves them is
seen; on (a) the planner beats both baselines on these six runs (18.8 % +- 5.7 % against
holding course, 18.5 % +- 6.4 % against random beams), which the 100 runs do not confirm."""

from __future__ import annotations

import pytest

from activetrack_experiments import multitarget

RUNS = 6
# GOSPA [m] of planner, hold_course, random_assignment on runs 0-5 (measured; the one loop
# draws each alive target's detection in a scan whether it is in view or not, so these runs
# differ from those of the separate multi-target loop before it, which gave (a) 53.03, 118.38,
# 122.71; (b) 69.70, 77.46, 227.80; (c) 72.04, 75.25, 79.34).
MEASURED = {
    "mt_bearings_crossing": (57.67, 71.05, 70.75),
    "mt_radars_beams": (136.71, 117.14, 225.70),
    "mt_appear_disappear": (67.65, 87.11, 86.69),
}


@pytest.fixture(scope="module")
def result():
    return multitarget.reproduce(RUNS, jobs=2)


@pytest.mark.parametrize("name", sorted(MEASURED))
def test_each_strategy_keeps_its_figures(result, name):
    sc = next(s for s in result.scenarios if s.name == name)
    got = tuple(sc.mean(strategy) for strategy in multitarget.STRATEGIES)
    assert got == pytest.approx(MEASURED[name], rel=0.02)


def test_the_planner_beats_both_baselines_on_scenario_a(result):
    sc = result.scenarios[0]
    assert sc.name == "mt_bearings_crossing"
    for baseline in multitarget.BASELINES:
        gain, se = sc.improvement(baseline), sc.improvement_stderr(baseline)
        assert gain > 2.0 * se and gain > 0.2 - se, (baseline, gain, se)
    assert sc.summaries["planner"].breaks == 0.0


def test_random_beams_lose_targets_on_scenario_b(result):
    """Five targets, three beams: pointing them at random loses tracks (breaks) that the MRE
    assignment keeps."""
    sc = result.scenarios[1]
    assert sc.improvement("random_assignment") > 0.3
    planner, rand = sc.summaries["planner"], sc.summaries["random_assignment"]
    assert rand.breaks > planner.breaks


def test_the_report_states_the_verdict(result):
    text = multitarget.format_report(result)
    assert "mt_bearings_crossing" in text and "hold_course" in text
    assert "(MISSES the 20% target)" in text
    rows = result.table()
    assert [r["strategy"] for r in rows] == list(multitarget.STRATEGIES) * 3
