"""benchmarks/filters.py's speed ratios: the median of per-run paired ratios over the runs both
implementations did (issue 28). No timing is asserted."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "filters.py"
_spec = importlib.util.spec_from_file_location("bench_filters", _PATH)
assert _spec is not None and _spec.loader is not None
bf = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = bf  # dataclasses look their module up while the class is built
_spec.loader.exec_module(bf)


def _result(name: str, per_run_medians: list[float], n_steps: int = 3) -> object:
    """A Result whose run r has median step ``per_run_medians[r]`` (steps m/2, m, 4m)."""
    times = np.concatenate([[m / 2, m, 4 * m] for m in per_run_medians])
    seeds = list(range(len(per_run_medians)))
    return bf.Result(name, times, np.zeros((len(seeds), n_steps)), seeds)


def test_paired_speedup_over_the_common_runs():
    """Ours did 5 runs, theirs the first 3: ratios 10, 40, 20 on those (median 20x); our two
    extra (slow) runs do not enter, though they halve a ratio of pooled medians."""
    ours = _result("ours", [1.0, 1.0, 2.0, 50.0, 50.0])
    theirs = _result("theirs", [10.0, 40.0, 40.0])
    np.testing.assert_allclose(bf.paired_ratios(theirs, ours, 3), [10.0, 40.0, 20.0])
    med, lo, hi = bf.paired_speedup(theirs, ours, 3)
    assert med == pytest.approx(20.0)
    assert lo == pytest.approx(12.0) and hi == pytest.approx(36.0)
    # The old headline, the ratio of medians over each one's own runs: 40 / 4 = 10x.
    assert theirs.median_step / ours.median_step == pytest.approx(10.0)
