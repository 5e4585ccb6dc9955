"""TargetBound (one epoch at a time, for a run in progress) equals target_bounds (the
summary's), for one target and for targets born and dying."""

import numpy as np
import pytest

from activetrack.closed_loop.components import component_rngs, scene_targets
from activetrack.closed_loop.evaluation import (
    TargetBound,
    bound_counts,
    bound_sensors,
    target_bounds,
)
from activetrack.closed_loop.loop import run_once
from activetrack.scenarios import load_scenario


@pytest.mark.parametrize(
    "name, steps",
    [
        ("tests/ros/data/short_two_sensors.yaml", None),
        ("scenarios/ramdaras_case3_pd.yaml", 12),
        ("scenarios/mt_appear_disappear.yaml", 45),
    ],
)
def test_stepwise_bound_equals_the_summary_bound(name, steps):
    sc = load_scenario(name)
    if steps is not None:  # shorter, and a cheaper planner: the bound is what is tested
        planner = sc.planner.model_copy(update={"mc_samples": 20})
        sc = sc.model_copy(update={"steps": steps, "planner": planner})
    record = run_once(sc, None)
    whole = target_bounds(sc, record, component_rngs(sc.seed, None)[3])
    sensors, columns = bound_sensors(sc)
    paths = record.platform_paths[:, columns]
    counts = bound_counts(sensors, record.looked, record.observed)
    rng = component_rngs(sc.seed, None)[3]  # the same stream, target after target
    steps_ = []
    for n, target in enumerate(scene_targets(sc)):
        tb = TargetBound(target, sensors, sc.dt, rng)
        steps_.append([tb.step(paths[k], counts[k - 1, :, n]) for k in range(1, sc.steps + 1)])
    stepwise = np.stack(steps_, axis=1)  # (K, N, 4, 4)
    alive = ~np.isnan(record.truth[1:, :, 0])
    # NaN exactly where a target is not alive; sensors that do not count at some epochs
    # (ramdaras: selection; mt: beams pointed elsewhere), except short (always two sensors)
    np.testing.assert_array_equal(np.isfinite(whole).all(axis=(2, 3)), alive)
    assert not counts.all() or "short" in name
    # equal to round-off relative to each bound's scale (an off-diagonal entry can be ~0)
    scale = np.nan_to_num(np.abs(whole)).max(axis=(2, 3), keepdims=True)
    np.testing.assert_array_equal(np.isnan(stepwise), np.isnan(whole))
    diff = np.nan_to_num(np.abs(stepwise - whole))
    assert (diff <= 1e-12 * scale).all(), diff.max()


def test_nonlinear_motion_gives_nan():
    sc = load_scenario("scenarios/valverde_circular.yaml")
    sensors, _ = bound_sensors(sc)
    tb = TargetBound(scene_targets(sc)[0], sensors, sc.dt, np.random.default_rng(0))
    assert np.isnan(tb.step(np.zeros((len(sensors), 4)), np.ones(len(sensors), bool))).all()
