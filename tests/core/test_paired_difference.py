"""Paired differences with Student-t intervals (activetrack.montecarlo.paired)."""

import math

import numpy as np
import pytest

from activetrack.montecarlo.paired import paired_difference


def test_interval_matches_the_t_formula():
    a = np.array([10.0, 12.0, 9.0, 11.0, 13.0])
    b = np.array([8.0, 11.0, 9.5, 9.0, 10.0])
    d = a - b  # 2, 1, -0.5, 2, 3: mean 1.5, sd sqrt(1.75)
    res = paired_difference(a, b)
    assert res.mean == pytest.approx(1.5)
    assert res.stderr == pytest.approx(math.sqrt(1.75 / 5))
    # t_{0.975, 4} = 2.7764451051977987
    assert res.high - res.mean == pytest.approx(2.7764451051977987 * res.stderr)
    assert res.low == pytest.approx(1.5 - 2.7764451051977987 * math.sqrt(1.75 / 5))
    assert res.runs == 5 and res.resolved == (res.low > 0)
    assert d.mean() == pytest.approx(res.mean)


def test_pairing_removes_the_common_world():
    rng = np.random.default_rng(3)
    world = rng.normal(100.0, 30.0, 200)  # what both policies share
    a = world + rng.normal(-2.0, 1.0, 200)
    b = world + rng.normal(0.0, 1.0, 200)
    res = paired_difference(a, b)
    assert res.high < 0.0 and res.resolved
    assert res.stderr < 0.2  # 30 m of world spread cancels; unpaired SE would be ~3 m


def test_coverage_of_the_95_interval_is_95_percent():
    rng = np.random.default_rng(11)
    inside = 0
    for _ in range(4000):
        r = paired_difference(rng.normal(1.0, 2.0, 10), rng.normal(0.0, 2.0, 10))
        inside += r.low <= 1.0 <= r.high
    assert 0.94 <= inside / 4000 <= 0.96


def test_bad_input_is_refused_naming_what():
    with pytest.raises(ValueError, match="one value per run"):
        paired_difference([1.0, 2.0], [1.0])
    with pytest.raises(ValueError, match="finite"):
        paired_difference([1.0, math.nan], [1.0, 2.0])
    with pytest.raises(ValueError, match="level"):
        paired_difference([1.0, 2.0], [1.0, 2.0], level=1.0)
    one = paired_difference([3.0], [1.0])
    assert one.mean == 2.0 and math.isnan(one.low) and not one.resolved
