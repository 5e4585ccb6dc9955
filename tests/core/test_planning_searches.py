"""Searches over the reachable region: evaluation counts, optimality on known functions and on
a Hernandez decision, lockstep batching."""

import numpy as np
import pytest

from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import BearingSensor
from activetrack.planning import (
    PlannerPlatform,
    PlanSettings,
    PlatformLimits,
    TargetBelief,
    evolution_search,
    grid_search,
    plan,
    quadrant_search,
    sector_search,
)
from activetrack.scenarios.build import plan_settings


def bowl(centre):
    """Cost (u - c)^2 summed over the two coordinates, c per problem ``(B, 2)``."""
    centre = np.asarray(centre, dtype=float)

    def cost_fn(rows, u):
        return np.sum((u - centre[rows, None, :]) ** 2, axis=-1)

    return cost_fn


def hernandez_decision(n_samples=400):
    """The first decision of the Hernandez 1-sensor scenario (sec. 5.1)."""
    model = NearlyConstantVelocity(q=1e-8)
    F, Q = model.transition_matrix(5.0), model.process_noise(5.0)
    rng = np.random.default_rng(7)
    belief = TargetBelief.from_gaussian(
        [1000.0, -40.0, 1000.0, -40.0], np.diag([10.0, 1.0, 10.0, 1.0]), n_samples, rng
    )
    limits = PlatformLimits(np.pi / 10, 10.0, 50.0, 200.0)
    platform = PlannerPlatform(
        "p1", np.array([1800.0, -40.0, 2000.0, -40.0]), (BearingSensor(0.01, r_min=1000.0),), limits
    )
    return [platform], belief, F, Q


def test_quadrant_search_spends_at_most_34_evaluations_and_finds_the_bowl_minimum():
    c = np.array([[0.3, 0.8]])
    res = quadrant_search(bowl(c), 1, divisions=6)
    assert res.evaluations == 34  # 9 + 5 x 5 (Hernandez sec. 4.2)
    # After 6 halvings the grid spacing is 1/64: the best point is within one spacing.
    assert np.all(np.abs(res.u[0] - c[0]) <= 1.0 / 64 + 1e-12)
    assert res.cost[0] == pytest.approx(np.sum((res.u[0] - c[0]) ** 2))


def test_quadrant_search_patience_stops_early():
    # A constant cost never improves after the first division: stop after `patience` more.
    res = quadrant_search(lambda rows, u: np.zeros(u.shape[:2]), 1, divisions=6, patience=2)
    assert res.evaluations == 9 + 5 * 2


def test_lockstep_batch_equals_separate_searches():
    centres = np.array([[0.1, 0.2], [0.9, 0.45], [0.5, 0.5]])
    batch = quadrant_search(bowl(centres), 3)
    for b in range(3):
        one = quadrant_search(bowl(centres[b : b + 1]), 1)
        np.testing.assert_array_equal(batch.u[b], one.u[0])
        assert batch.cost[b] == one.cost[0]
    assert batch.evaluations == 3 * 34


def test_grid_search_is_exact_on_grid_points_and_counts_all_points():
    c = np.array([[0.25, 0.75]])
    res = grid_search(bowl(c), 1, size=5, chunk=7)  # chunking must not matter
    np.testing.assert_allclose(res.u[0], [0.25, 0.75])
    assert res.cost[0] == 0.0
    assert res.evaluations == 25


def test_sector_search_returns_a_sector_centre_and_admits_straight_ahead():
    # Minimum exactly straight ahead at unchanged speed (u = (0.5, 0.5)).
    res = sector_search(bowl([[0.5, 0.5]]), 1, levels=3)
    assert res.evaluations == 16 + 12 * 2 + 1
    np.testing.assert_allclose(res.u[0], [0.5, 0.5], atol=1e-12)
    res = sector_search(bowl([[0.2, 0.9]]), 1, levels=4)
    assert np.all(np.abs(res.u[0] - [0.2, 0.9]) <= 0.5 / 3**4 + 1e-12)


def test_evolution_search_finds_a_4d_minimum():
    c = np.array([0.2, 0.7, 0.4, 0.9])

    def cost_fn(rows, u):
        return np.sum((u - c) ** 2, axis=-1)

    res = evolution_search(cost_fn, 4, np.random.default_rng(3), popsize=10, maxiter=200)
    np.testing.assert_allclose(res.u[0], c, atol=2e-3)
    assert res.evaluations > 0


def test_quadrant_decision_within_a_few_percent_of_the_101_grid():
    platforms, belief, F, Q = hernandez_decision()
    quad = plan(platforms, belief, PlanSettings(), F=F, Q=Q, dt=5.0)
    grid_settings = plan_settings(_cfg(), search="grid", grid_size=101)
    grid = plan(platforms, belief, grid_settings, F=F, Q=Q, dt=5.0)
    assert quad.report.evaluations <= 34
    assert grid.report.evaluations == 101 * 101
    assert grid.report.objective <= quad.report.objective + 1e-12
    assert quad.report.objective <= 1.03 * grid.report.objective


def _cfg():
    from activetrack.scenarios.schema import PlannerConfig

    return PlannerConfig()


@pytest.mark.parametrize(
    ("kwargs", "name"),
    [
        ({"size": 1}, "size"),
        ({"size": 2.5}, "size"),
    ],
)
def test_grid_search_rejects_bad_size(kwargs, name):
    with pytest.raises(ValueError, match=name):
        grid_search(bowl([[0.5, 0.5]]), 1, **kwargs)


def test_searches_reject_bad_arguments():
    with pytest.raises(ValueError, match="divisions"):
        quadrant_search(bowl([[0.5, 0.5]]), 1, divisions=0)
    with pytest.raises(ValueError, match="patience"):
        quadrant_search(bowl([[0.5, 0.5]]), 1, patience=0)
    with pytest.raises(ValueError, match="levels"):
        sector_search(bowl([[0.5, 0.5]]), 1, levels=0)
    with pytest.raises(ValueError, match="n_problems"):
        quadrant_search(bowl([[0.5, 0.5]]), 0)
    with pytest.raises(ValueError, match="cost_fn"):
        quadrant_search(lambda rows, u: np.zeros(3), 1)
