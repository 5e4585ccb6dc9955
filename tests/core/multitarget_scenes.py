"""What the scene modules of ``activetrack reproduce multitarget`` share
(test_multitarget_reproduction_a.py to _e.py).

Each module reproduces its one scene on one process: the suite's workers take the files apart
(``--dist loadfile``), so the five scenes spread over them and none runs a pool of its own
beside the other worker. The strategies run on common random numbers (run r of each is the same
world), so the report's paired differences carry no world noise; a scene's seeded runs must
keep their figures (each module's MEASURED), so that a change that moves them is seen.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from activetrack.montecarlo.paired import paired_difference
from activetrack_experiments import multitarget


def reproduce_scene(name: str, runs: int, stonesoup: bool | None = False):
    """Every strategy on scene ``name``, runs 0..runs-1 (runs > 1), on this process."""
    return multitarget.reproduce(runs, scenarios=(name,), jobs=1, stonesoup=stonesoup)


def assert_keeps_its_figures(result, measured: tuple[float, float, float]) -> None:
    """The mean GOSPA of planner, hold_course and random_assignment, as measured (2 %)."""
    (sc,) = result.scenarios
    got = tuple(sc.mean(strategy) for strategy in multitarget.STRATEGIES)
    assert got == pytest.approx(measured, rel=0.02)


def assert_the_report_states_the_verdict(result) -> None:
    """The report's table rows, paired differences, verdict line and last line are the
    result's, for every scene it holds."""
    text = multitarget.format_report(result)
    names = [sc.name for sc in result.scenarios]
    assert all(name in text for name in names) and "hold_course" in text
    verdict = next(line for line in text.splitlines() if line.startswith("margin below"))
    for sc in result.scenarios:
        letter, margin = multitarget.LETTERS[sc.name], multitarget.MARGINS[sc.name]
        met = sc.gain_vs_best_baseline() >= margin and all(
            sc.paired(b).high < 0 for b in multitarget.BASELINES
        )
        assert f"{letter} {100 * margin:.0f}%: {'met' if met else 'MISSED'}" in verdict
    missed = "MISSED" in verdict
    assert (multitarget.MISSED_NOTE in text.splitlines()) == missed
    rows = result.table()
    assert [r["strategy"] for r in rows] == list(multitarget.STRATEGIES) * len(names)
    assert [r["scenario"] for r in rows] == [n for n in names for _ in multitarget.STRATEGIES]
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
    letters = ",".join(f"{multitarget.LETTERS[n]}:(\\S+)" for n in names)
    m = re.fullmatch(rf"planner_gain_vs_best_baseline_pct={letters}", last)
    assert m is not None, last
    for got, sc in zip(m.groups(), result.scenarios, strict=True):
        best = min(sc.mean(b) for b in multitarget.BASELINES)
        assert float(got) == pytest.approx(100 * (1 - sc.mean("planner") / best), abs=0.05)
