"""``activetrack reproduce multitarget`` on the five scenarios, six seeded runs per strategy.

The multi-target issue's criterion (>= 20 % lower time-averaged GOSPA than both baselines over
100 runs) is judged by the reproduction command (docs/multitarget.md). The strategies run on
common random numbers (run r of each is the same world), so the report's paired differences
carry no world noise. Here the same six seeded runs of each strategy must keep their figures
(measured values in MEASURED), so that a change that moves them is seen."""

from __future__ import annotations

import re

import numpy as np
import pytest

from activetrack.montecarlo.paired import paired_difference
from activetrack_experiments import multitarget

RUNS = 6
# GOSPA [m] of planner, hold_course, random_assignment on runs 0-5 (measured on common random
# numbers; on the one generator before them: (a) 57.67, 71.05, 70.75; (b) 136.71, 117.14,
# 225.70; (c) 67.65, 87.11, 86.69). On (a) the JPDA-EKF planner on planner.criterion lost a
# target for good in runs 3 and 4 (203.3 and 309.7 m: a prior's bearings-only track drifted
# off while the beams served the others); particle tracks planning on the expected GOSPA lose
# none. Before existence terminated tracks from priors: (a) 149.18, 74.35, 114.28; (b)
# 111.04, 94.89, 165.87; (c) 73.29, 78.09, 92.80.
MEASURED = {
    # (a) with particle tracks and the expected-GOSPA objective over two epochs (its file says
    # why); before, JPDA-EKF on planner.criterion: 129.56, 74.35, 107.24
    "mt_bearings_crossing": (59.31, 66.16, 98.95),
    # (b) with the information reduction of the tracker's gate on S (clutter_gate:
    # innovation); before, one q per sensor of R: 114.58, 86.28, 159.36; before a beam's
    # missed looks said less as the track's prediction widened: 110.81, 87.53, 160.71
    "mt_radars_beams": (66.01, 107.44, 138.51),
    # (c) ends the prior's track at existence 0.02 (its file says why); before, with the
    # default prior threshold: 73.96, 76.11, 97.42
    "mt_appear_disappear": (66.93, 71.29, 98.08),
    # (d) plans on the expected GOSPA with its surveillance region (search versus track), its
    # rollout scoring each manoeuvre with the search it allows and counting the tracker's
    # termination; before that 440.73, 442.26, 581.38; on planner.criterion with beams on
    # tracks only: 487.96, 453.21, 485.06
    "mt_search_track": (373.38, 442.26, 571.10),
    # (e) on particle tracks with beams pointed at footprints (its file says why); before,
    # JPDA-EKF with one track per beam: 44.11, 46.76, 49.52; before missed looks aged with
    # the prediction's spread (the planner's run 0 now loses a target): 37.26 for the planner
    "mt_mixed_platforms": (45.71, 47.13, 58.25),
}


@pytest.fixture(scope="module")
def result():
    return multitarget.reproduce(RUNS, jobs=2, stonesoup=False)


@pytest.mark.parametrize("name", sorted(MEASURED))
def test_each_strategy_keeps_its_figures(result, name):
    sc = next(s for s in result.scenarios if s.name == name)
    got = tuple(sc.mean(strategy) for strategy in multitarget.STRATEGIES)
    assert got == pytest.approx(MEASURED[name], rel=0.02)


@pytest.mark.xfail(
    strict=True,
    reason="issue 25: on six runs the planner is ahead of both baselines on (a) (59.3 against "
    "66.2 and 99.0 m) but not by two standard errors; 20 runs resolve it against hold course "
    "(docs/multitarget.md)",
)
def test_the_planner_beats_both_baselines_on_scenario_a(result):
    sc = result.scenarios[0]
    assert sc.name == "mt_bearings_crossing"
    for baseline in multitarget.BASELINES:
        gain, se = sc.improvement(baseline), sc.improvement_stderr(baseline)
        assert gain > 2.0 * se and gain > 0.2 - se, (baseline, gain, se)
    assert sc.summaries["planner"].breaks == 0.0


def test_the_planner_is_ahead_of_both_baselines_on_scenario_a_and_loses_no_target(result):
    """(a)'s six runs: the planner's mean GOSPA below both baselines' and no target missed at
    any epoch of any run (measured: 59.3 against 66.2 and 99.0 m; random beams miss 0.04 per
    epoch)."""
    sc = result.scenarios[0]
    assert sc.name == "mt_bearings_crossing"
    for baseline in multitarget.BASELINES:
        assert sc.improvement(baseline) > 0.05, baseline
    assert sc.split("planner")[1] == 0.0


def test_the_planner_is_ahead_of_both_baselines_on_scenario_e(result):
    """(e)'s six runs: the planner's mean GOSPA below both baselines' and its localisation
    (beams at footprints update several tracks a look) at least 10 % below hold course's
    (measured: 45.7 against 47.1 and 58.3 m, 1619 against 1922 m^2 per epoch; the planner's
    run 0 loses a target, 87.4 m; 20 runs: 21.1 % below the better baseline, planner - hold
    course -11.1 [-20.4, -1.8] m)."""
    sc = result.scenarios[4]
    assert sc.name == "mt_mixed_platforms"
    for baseline in multitarget.BASELINES:
        assert sc.improvement(baseline) > 0.02, baseline
    assert sc.split("planner")[0] < 0.9 * sc.split("hold_course")[0]


def test_the_planner_is_ahead_of_both_baselines_on_scenario_d(result):
    """(d)'s six runs: its manoeuvres scored with the search they allow, the planner's mean
    GOSPA is below both baselines' (measured: 373.4 against 442.3 and 571.1 m) and it finds
    the entering targets sooner than hold course (missed 1.03 against 1.70 per epoch)."""
    sc = next(s for s in result.scenarios if s.name == "mt_search_track")
    for baseline in multitarget.BASELINES:
        assert sc.improvement(baseline) > 0.08, baseline
    assert sc.split("planner")[1] < sc.split("hold_course")[1] - 0.4


def test_random_beams_lose_targets_on_scenario_b(result):
    """Five targets, three beams: pointing them at random loses tracks (breaks) that the MRE
    assignment keeps."""
    sc = result.scenarios[1]
    assert sc.improvement("random_assignment") > 0.25  # measured 0.28
    planner, rand = sc.summaries["planner"], sc.summaries["random_assignment"]
    # Runs that lost a target for good (GOSPA above c / 2 = 250 m; measured: random 2 of 6,
    # the planner 1). Breaks do not tell them apart (measured: planner 0.50, random 0.33 per
    # run): since a confirmed track from a prior is terminated on existence, a lost target's
    # track ends (a break) instead of staying on as a false track.
    lost = {s: sum(g > 250.0 for g in x.run_gospa) for s, x in (("p", planner), ("r", rand))}
    assert lost["r"] > lost["p"]


def test_the_report_states_the_verdict(result):
    text = multitarget.format_report(result)
    assert "mt_bearings_crossing" in text and "hold_course" in text
    verdict = next(line for line in text.splitlines() if line.startswith("margin below"))
    for sc in result.scenarios:
        letter, margin = multitarget.LETTERS[sc.name], multitarget.MARGINS[sc.name]
        met = sc.gain_vs_best_baseline() >= margin and all(
            sc.paired(b).high < 0 for b in multitarget.BASELINES
        )
        assert f"{letter} {100 * margin:.0f}%: {'met' if met else 'MISSED'}" in verdict
    rows = result.table()
    assert [r["strategy"] for r in rows] == list(multitarget.STRATEGIES) * 5
    assert result.manager_note == ""  # left out on purpose (stonesoup=False): no note
    # the paired differences, run by run, with their 95 % intervals, as computed by hand
    for sc in result.scenarios:
        planner = np.array(sc.summaries["planner"].run_gospa)
        for b in multitarget.BASELINES:
            d = paired_difference(planner, sc.summaries[b].run_gospa)
            assert d.mean == pytest.approx(np.mean(planner - sc.summaries[b].run_gospa))
            row = next(r for r in rows if r["scenario"] == sc.name and r["strategy"] == b)
            assert (row["paired_diff_m"], row["paired_low_m"], row["paired_high_m"]) == (
                d.mean,
                d.low,
                d.high,
            )
            assert f"{d.mean:+9.1f} [{d.low:+8.1f}, {d.high:+8.1f}]" in text
    last = text.splitlines()[-1]
    m = re.fullmatch(
        r"planner_gain_vs_best_baseline_pct=a:(\S+),b:(\S+),c:(\S+),d:(\S+),e:(\S+)", last
    )
    assert m is not None, last
    for got, sc in zip(m.groups(), result.scenarios, strict=True):
        best = min(sc.mean(b) for b in multitarget.BASELINES)
        assert float(got) == pytest.approx(100 * (1 - sc.mean("planner") / best), abs=0.05)


# GOSPA [m] of runs 0 and 1 of (d) per strategy, Stone Soup's manager among them (measured).
MANAGER_RUNS_D = {
    "planner": (368.49, 396.17),
    "hold_course": (431.97, 502.72),
    "random_assignment": (496.79, 530.41),
    multitarget.MANAGER: (444.34, 510.50),
}


def test_stonesoup_manager_runs_paired_on_scenario_d():
    """On (d) Stone Soup's manager is a fourth strategy on the same worlds: its runs keep their
    figures, its paired difference is in the rows and the report."""
    pytest.importorskip("stonesoup")
    res = multitarget.reproduce(2, scenarios=("mt_search_track",), jobs=2, stonesoup=True)
    (sc,) = res.scenarios
    assert sc.strategies == (*multitarget.STRATEGIES, multitarget.MANAGER)
    for strategy, measured in MANAGER_RUNS_D.items():
        assert sc.summaries[strategy].run_gospa == pytest.approx(measured, abs=0.01), strategy
    d = sc.paired(multitarget.MANAGER)
    manager = np.array(sc.summaries[multitarget.MANAGER].run_gospa)
    assert d.mean == pytest.approx(np.mean(np.array(sc.summaries["planner"].run_gospa) - manager))
    text = multitarget.format_report(res)
    assert f"- {multitarget.MANAGER}" in text and res.manager_note == ""
    row = next(r for r in res.table() if r["strategy"] == multitarget.MANAGER)
    assert row["paired_diff_m"] == d.mean
    # the gain is against hold course and random beams only
    assert text.splitlines()[-1] == (
        f"planner_gain_vs_best_baseline_pct=d:{100 * sc.gain_vs_best_baseline():.1f}"
    )


def test_without_stonesoup_the_report_says_so_and_the_rest_runs(monkeypatch):
    monkeypatch.setattr(multitarget.stonesoup_manager, "available", lambda: False)
    res = multitarget.reproduce(1, scenarios=("mt_search_track",), jobs=1)
    (sc,) = res.scenarios
    assert sc.strategies == multitarget.STRATEGIES
    assert "stonesoup is not installed" in res.manager_note
    assert res.manager_note in multitarget.format_report(res).splitlines()
