"""TrackerCore.snapshot() is pure: looking at the track never changes a later result."""

import numpy as np

from activetrack.closed_loop.simulator import Simulator
from activetrack.closed_loop.tracker import TrackerCore
from activetrack.scenarios import load_scenario, with_tracker_overrides

SCENARIO = "tests/ros/data/short_two_sensors.yaml"


def test_snapshots_draw_nothing():
    scenario = with_tracker_overrides(load_scenario(SCENARIO), filter="pf", particles=500)
    plain, looked = (TrackerCore(scenario, np.random.default_rng(3)) for _ in range(2))
    sim = Simulator(scenario, np.random.default_rng(4))
    for k in range(1, 6):
        measurements = sim.advance()
        a = plain.step(k, sim.time, measurements)
        for _ in range(3):  # a notebook looking at the track, again and again
            b = looked.snapshot()
        b = looked.step(k, sim.time, measurements)
        again = looked.snapshot()
        np.testing.assert_array_equal(a.mean, b.mean)
        np.testing.assert_array_equal(a.samples, b.samples)
        np.testing.assert_array_equal(again.samples, b.samples)  # the same samples each look
