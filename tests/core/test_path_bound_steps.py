"""PathBound (one epoch at a time, for a run in progress) equals path_bound (the summary's)."""

import numpy as np
import pytest

from activetrack.closed_loop.batch import PathBound, component_rngs, path_bound, run_once
from activetrack.scenarios import load_scenario


@pytest.mark.parametrize(
    "name", ["tests/ros/data/short_two_sensors.yaml", "scenarios/ramdaras_case3_pd.yaml"]
)
def test_stepwise_bound_equals_the_summary_bound(name):
    sc = load_scenario(name)
    if "ramdaras" in name:
        sc = sc.model_copy(update={"steps": 12})
    record = run_once(sc, None)
    whole = path_bound(sc, record, component_rngs(sc.seed, None)[3])
    pb = PathBound(sc, component_rngs(sc.seed, None)[3])
    steps = np.stack(
        [pb.step(record.platform_paths[k], record.measured[k - 1]) for k in range(1, sc.steps + 1)]
    )
    assert (np.isfinite(whole).all() and not record.measured.all()) or "short" in name
    np.testing.assert_allclose(steps, whole, rtol=1e-12, atol=0)


def test_nonlinear_motion_gives_nan():
    sc = load_scenario("scenarios/valverde_circular.yaml")
    pb = PathBound(sc, np.random.default_rng(0))
    assert np.isnan(pb.step(np.zeros((1, 4)), np.ones(1, dtype=bool))).all()
