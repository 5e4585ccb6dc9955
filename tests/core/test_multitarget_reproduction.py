"""``activetrack reproduce multitarget``: its report over the five scenes, and Stone Soup's
manager as a fourth strategy on (d).

Each scene's seeded runs, their figures and what they show are in its own module
(test_multitarget_reproduction_a.py to _e.py, sharing multitarget_scenes.py), so that the
suite's workers take the scenes apart."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest
from multitarget_scenes import assert_the_report_states_the_verdict

from activetrack_experiments import multitarget


def _summary(run_gospa, missed_per_epoch):
    """The figures of one strategy's runs that the report reads."""
    return SimpleNamespace(
        runs=len(run_gospa),
        run_gospa=list(run_gospa),
        mean_gospa=float(np.mean(run_gospa)),
        breaks=0.5,
        swaps=0.25,
        localisation_t=[900.0, 1100.0],
        missed_t=[missed_per_epoch, missed_per_epoch],
        false_t=[0.125, 0.0],
    )


# GOSPA [m] of three runs of planner, hold_course, random_assignment per scene: (a) and (e) 20 %
# and more below the better baseline, (b) 9.2 % (its margin is 5 %), (c) above hold course, (d)
# 10 % below (its margin is 20 %).
RUNS_OF = {
    "mt_bearings_crossing": ((50.0, 52.0, 51.0), (70.0, 75.0, 72.0), (80.0, 85.0, 90.0)),
    "mt_radars_beams": ((90.0, 95.0, 92.0), (100.0, 104.0, 101.0), (150.0, 170.0, 160.0)),
    "mt_appear_disappear": ((70.0, 66.0, 75.0), (65.0, 64.0, 70.0), (90.0, 99.0, 95.0)),
    "mt_search_track": ((390.0, 400.0, 380.0), (430.0, 450.0, 420.0), (560.0, 580.0, 570.0)),
    "mt_mixed_platforms": ((40.0, 44.0, 42.0), (55.0, 60.0, 58.0), (60.0, 66.0, 62.0)),
}


def test_the_report_over_the_five_scenes_states_each_verdict_in_order():
    res = multitarget.MultiTargetResult(3)
    for name in multitarget.SCENARIOS:
        runs = dict(zip(multitarget.STRATEGIES, RUNS_OF[name], strict=True))
        summaries = {s: _summary(g, 0.5) for s, g in runs.items()}
        res.scenarios.append(multitarget.ScenarioResult(name, summaries))
    assert_the_report_states_the_verdict(res)
    text = multitarget.format_report(res)
    assert (
        "margin below the better baseline, both paired intervals below zero: "
        "a 20%: met, b 5%: met, c 5%: MISSED, d 20%: MISSED, e 20%: met"
    ) in text.splitlines()
    assert text.splitlines()[-1] == (
        "planner_gain_vs_best_baseline_pct=a:29.5,b:9.2,c:-6.0,d:10.0,e:27.2"
    )


# GOSPA [m] of runs 0 and 1 of (d) per strategy, Stone Soup's manager among them (measured;
# the tracker reporting by expected GOSPA, as (d)'s file has it).
MANAGER_RUNS_D = {
    "planner": (290.70, 473.61),
    "hold_course": (431.97, 500.50),
    "random_assignment": (449.92, 534.45),
    multitarget.MANAGER: (444.34, 504.68),
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


def test_the_command_prints_the_gain_key_as_its_last_line(capsys):
    """What ``activetrack reproduce multitarget`` prints ends with the gain key (the figures
    written and the wall time go to stderr), so ``| tail -1`` reads it."""
    argv = ["--scenario", "mt_radars_beams", "--runs", "1", "--no-stonesoup", "--no-figures"]
    assert multitarget.main(argv) == 0
    out, err = capsys.readouterr()
    assert out.rstrip("\n").splitlines()[-1].startswith("planner_gain_vs_best_baseline_pct=b:")
    assert "wall time" in err and "wall time" not in out
