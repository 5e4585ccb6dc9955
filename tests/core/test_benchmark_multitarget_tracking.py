"""benchmarks/multitarget_tracking.py: our tracker with its default track management on the
benchmark's scenes with priors 3 sigma off (pinned, no Stone Soup needed), and against Stone
Soup's JPDA with its own initiator and deleter (skipped without Stone Soup, bench-only).

Figures (seeds 3000-3001, 3 and 4 targets, 40 scans; measured values in PINNED):
time-averaged GOSPA (c = 500 m, p = 2) of our tracker, pinned to 1 % (the runs are seeded;
1 % leaves room for rounding across machines, not for a change of rule: terminating every
confirmed track at 0.1 instead of the defaults moves the radar's run 3001 by 5 %)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "multitarget_tracking.py"
_spec = importlib.util.spec_from_file_location("bench_multitarget_tracking", _PATH)
assert _spec is not None and _spec.loader is not None
bench = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = bench  # dataclasses look their module up while the class is built
_spec.loader.exec_module(bench)

SEEDS = (3000, 3001)
# Our time-averaged GOSPA [m] on SEEDS with priors 3 sigma off (3 and 4 targets).
PINNED = {"radar": (211.47, 244.54), "bearings": (242.67, 340.84)}
# Stone Soup measured 242.46 and 341.19 m on the bearings runs (the two agree to 0.4 m: no
# track is deleted, the same maths); ours may exceed it by this much [m].
MARGIN = 1.0


def _world(scene: str, i: int):
    return bench.simulate(scene, "3sigma", SEEDS[i], 3 + i)


def test_priors_3_sigma_off_are_3_sigma_off_on_the_drawn_worlds():
    for i in range(2):
        off, drawn = _world("radar", i), bench.simulate("radar", "drawn", SEEDS[i], 3 + i)
        np.testing.assert_array_equal(off.truth, drawn.truth)  # one world, two priors
        for a, b in zip(off.scans, drawn.scans, strict=True):
            np.testing.assert_array_equal(a[0], b[0])
        e = (off.prior_means - off.truth[0]) / np.sqrt(np.diag(off.prior_cov))
        np.testing.assert_allclose(np.linalg.norm(e, axis=1), 3.0, rtol=1e-12)


@pytest.mark.parametrize("scene", sorted(PINNED))
def test_our_gospa_with_priors_3_sigma_off_is_pinned(scene):
    got = [bench.mean_gospa(w, bench.run_ours(scene, w)) for w in map(
        lambda i: _world(scene, i), range(2))]  # fmt: skip
    assert got == pytest.approx(PINNED[scene], rel=0.01)


def test_ours_no_worse_than_stonesoup_on_bearings_with_priors_3_sigma_off():
    """Both from the same priors 3 sigma off on the same bearings (Stone Soup's radar runs take
    a minute each here: the benchmark itself compares those)."""
    pytest.importorskip("stonesoup")
    for i in range(2):
        world = _world("bearings", i)
        ours = bench.mean_gospa(world, bench.run_ours("bearings", world))
        theirs = bench.mean_gospa(world, bench.run_stonesoup("bearings", world))
        assert ours <= theirs + MARGIN, (i, ours, theirs)
