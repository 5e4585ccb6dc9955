"""Three-step (R = 3) receding-horizon planning (Hernandez eq. 16: the DP of eq. 13-15 nested
three deep): exact on a small grid against brute force, the quadrant search's evaluation count,
the scenario files that select it, compiled and numpy planners alike."""

import itertools
from pathlib import Path

import numpy as np
import pytest

from activetrack.bounds import covariance_bound, pcrlb_trajectory, propagate_samples, rmse_bound
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import BearingSensor
from activetrack.planning import (
    PlannerPlatform,
    PlanSettings,
    PlatformLimits,
    SearchSettings,
    TargetBelief,
    plan,
    rollout,
    unit_to_manoeuvre,
)
from activetrack.scenarios import load_scenario
from activetrack_experiments.hernandez import plan_case

SCENARIOS = Path(__file__).parents[2] / "scenarios"
DT = 5.0
MODEL = NearlyConstantVelocity(q=1e-8)
F, Q = MODEL.transition_matrix(DT), MODEL.process_noise(DT)
LIMITS = PlatformLimits(np.pi / 10, 10.0, 50.0, 200.0)
SENSOR = BearingSensor(0.01, r_min=1000.0)


def _belief() -> TargetBelief:
    return TargetBelief.from_gaussian(
        [1000.0, -40.0, 1000.0, -40.0],
        np.diag([10.0, 1.0, 10.0, 1.0]),
        200,
        np.random.default_rng(3),
    )


def _platform() -> PlannerPlatform:
    return PlannerPlatform("p1", np.array([1800.0, -40.0, 2000.0, -40.0]), (SENSOR,), LIMITS)


def _sequences(p: PlannerPlatform, n: int) -> np.ndarray:
    """Every 3-leg manoeuvre sequence on an n x n grid of each leg's unit square:
    ``(n^2, n^2, n^2, 3, 2)``."""
    g = np.linspace(0.0, 1.0, n)
    units = np.array(list(itertools.product(g, g)))  # (n^2, 2)
    m1 = unit_to_manoeuvre(units, p.speed, LIMITS)[:, None, None, :]
    m2 = unit_to_manoeuvre(units[None, :, :], m1[:, 0, 0, None, 1], LIMITS)[:, :, None, :]
    m3 = unit_to_manoeuvre(units[None, None, :, :], m2[..., 1], LIMITS)
    return np.stack(np.broadcast_arrays(m1, m2, m3), axis=3)


@pytest.mark.parametrize("mode", ["compiled", "numpy"])
def test_three_step_dp_equals_brute_force_on_a_small_grid(mode, monkeypatch):
    monkeypatch.setenv("ACTIVETRACK_KERNELS", mode)
    n = 3
    b, p = _belief(), _platform()
    settings = PlanSettings(horizon=3, search=SearchSettings(search="grid", grid_size=n))
    res = plan([p], b, settings, F=F, Q=Q, dt=DT)
    samples = propagate_samples(b.samples, F, Q, 3)  # noise-free, as plan() with rng=None
    seqs = _sequences(p, n)
    path, _ = rollout(p.pv, p.heading, seqs, DT)  # (n^2, n^2, n^2, 3, 4)
    J = pcrlb_trajectory(b.J, F, Q, samples, SENSOR, np.moveaxis(path, 3, 0), method="numpy")
    total = np.sum(rmse_bound(covariance_bound(J)), axis=0)  # b_{k+1} + b_{k+2} + b_{k+3}
    best = np.unravel_index(np.argmin(total), total.shape)
    assert res.report.objective == pytest.approx(total[best], rel=1e-10)
    np.testing.assert_allclose(res.manoeuvres[0].plan, seqs[best], atol=1e-12)
    assert res.report.evaluations == n**2 + n**4 + n**6


@pytest.mark.parametrize("sensors", [1, 2, 3])
def test_three_step_scenarios_plan_with_the_quadrant_search(sensors, monkeypatch):
    monkeypatch.setenv("ACTIVETRACK_KERNELS", "compiled")
    scenario = load_scenario(SCENARIOS / f"hernandez_{sensors}sensor_three.yaml")
    two = load_scenario(SCENARIOS / f"hernandez_{sensors}sensor_two.yaml")
    assert scenario.planner.horizon == 3 and scenario.planner.search == "quadrant"
    # The same case as the two-step file but R = 3 (name, description and horizon differ).
    same = {"name", "description", "planner"}
    assert scenario.model_dump(exclude=same) == two.model_dump(exclude=same)
    assert scenario.planner.model_copy(update={"horizon": 2}) == two.planner
    steps = 2 if sensors < 3 else 1
    case = plan_case(scenario.model_copy(update={"steps": steps}))
    assert case.horizon == 3 and case.paths.shape == (steps + 1, sensors, 4)
    # One pass costs at most 34 + 34^2 + 34^3 per platform (Hernandez's 6-division search).
    per_platform = 34 + 34**2 + 34**3
    assert case.evaluations[0] >= per_platform
    assert case.evaluations[0] % per_platform == 0
    assert np.all(np.isfinite(case.bounds)) and np.all(case.bounds > 0.0)
