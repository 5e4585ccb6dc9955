"""Tracker.snapshot() is pure: looking at the tracks never changes a later result."""

import numpy as np

from activetrack.closed_loop.components import build_simulator, build_tracker
from activetrack.scenarios import load_scenario, with_tracker_overrides

SCENARIO = "tests/ros/data/short_two_sensors.yaml"


def test_snapshots_draw_nothing():
    scenario = with_tracker_overrides(load_scenario(SCENARIO), filter="pf", particles=500)
    plain, looked = (build_tracker(scenario, np.random.default_rng(3)) for _ in range(2))
    sim = build_simulator(scenario, np.random.default_rng(4))
    for k in range(1, 6):
        scans = sim.advance()
        (a,) = plain.step(k, sim.time, scans).tracks
        for _ in range(3):  # a notebook looking at the tracks, again and again
            looked.snapshot()
        (b,) = looked.step(k, sim.time, scans).tracks
        (again,) = looked.snapshot().tracks
        np.testing.assert_array_equal(a.mean, b.mean)
        np.testing.assert_array_equal(a.samples, b.samples)
        np.testing.assert_array_equal(again.samples, b.samples)  # the same samples each look
