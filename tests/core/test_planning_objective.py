"""The planning objective: a weighted sum of terms, summed over the legs or after the last.

- a mixed objective (the b_k of every leg, Hernandez eq. 15, plus a weighted terminal term
  written here, not in the library) is what the horizon search minimises: equal to brute force
  over every two-leg plan of a small grid, plan and value;
- the tracks' aggregates: worst (with the tie-break) and the priority-weighted sum;
- bad terms and aggregates fail naming the field.
"""

import itertools

import numpy as np
import pytest

from activetrack.bounds import covariance_bound, pcrlb_trajectory, propagate_samples, rmse_bound
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import BearingSensor
from activetrack.planning import (
    HorizonModel,
    InformationTerm,
    Objective,
    PlannerPlatform,
    PlatformLimits,
    SearchSettings,
    TargetBelief,
    TrackAggregate,
    get_criterion,
    rollout,
    search_horizon,
    unit_to_manoeuvre,
)
from activetrack.planning.objective import FINAL, TIE_BREAK

DT = 5.0
MODEL = NearlyConstantVelocity(q=1e-8)
F, Q = MODEL.transition_matrix(DT), MODEL.process_noise(DT)
LIMITS = PlatformLimits(np.pi / 10, 10.0, 50.0, 200.0)
SENSOR = BearingSensor(0.01, r_min=1000.0)


class NegLogDet:
    """A term the library does not have: -log det J of each track after the last leg (the
    D-optimal design), the worst track's."""

    weight = 5.0
    legs = FINAL

    def cost(self, state, level):
        return np.max(-np.linalg.slogdet(state)[1], axis=-1)


def test_a_mixed_objective_is_what_the_search_minimises():
    n, R = 4, 2
    belief = TargetBelief.from_gaussian(
        [1000.0, -40.0, 1000.0, -40.0],
        np.diag([10.0, 1.0, 10.0, 1.0]),
        200,
        np.random.default_rng(11),
    )
    p = PlannerPlatform("p1", np.array([1800.0, -40.0, 2000.0, -40.0]), (SENSOR,), LIMITS)
    samples = propagate_samples(belief.samples, F, Q, R)
    stage = HorizonModel(F, Q, samples, np.zeros((R, 4, 4)), p.sensors)
    objective = Objective((InformationTerm(get_criterion("b_k")), NegLogDet()))
    grid = SearchSettings("grid", grid_size=n)
    best = search_horizon(stage, objective, belief.J[None], p, DT, grid, R)

    g = np.linspace(0.0, 1.0, n)
    units = np.array(list(itertools.product(g, g)))  # (n^2, 2)
    m1 = unit_to_manoeuvre(units, p.speed, LIMITS)
    m2 = unit_to_manoeuvre(units[None, :, :], m1[:, None, 1], LIMITS)
    seqs = np.stack(np.broadcast_arrays(m1[:, None, :], m2), axis=2)  # (n^2, n^2, R, 2)
    path, _ = rollout(p.pv, p.heading, seqs, DT)
    J = pcrlb_trajectory(belief.J, F, Q, samples, SENSOR, np.moveaxis(path, 2, 0))
    total = np.sum(rmse_bound(covariance_bound(J)), axis=0) - 5.0 * np.linalg.slogdet(J[-1])[1]
    i, j = np.unravel_index(np.argmin(total), total.shape)
    assert best.objective == pytest.approx(total[i, j], rel=1e-10)
    np.testing.assert_allclose(best.plan, seqs[i, j], atol=1e-12)
    assert best.evaluations == n**2 + n**4
    # The terminal term moves the choice: b_k alone picks another plan.
    alone = search_horizon(
        stage, Objective((InformationTerm(get_criterion("b_k")),)), belief.J[None], p, DT, grid, R
    )
    assert not np.allclose(alone.plan, best.plan)


def test_track_aggregates_worst_with_tie_break_and_weighted_sum():
    c = np.array([[1.0, 3.0, 2.0], [4.0, 0.5, 0.5]])
    worst = TrackAggregate("worst", tie_break=TIE_BREAK)
    np.testing.assert_array_equal(worst(c), [3.0 + 6.0 * TIE_BREAK, 4.0 + 5.0 * TIE_BREAK])
    np.testing.assert_array_equal(TrackAggregate("worst")(c), [3.0, 4.0])
    weighted = TrackAggregate("weighted_sum", np.array([1.0, 2.0, 10.0]), tie_break=TIE_BREAK)
    np.testing.assert_array_equal(weighted(c), [27.0, 10.0])  # no tie-break for a sum
    # Terms add with their weights; a terminal term counts at the last leg only.
    info = InformationTerm(get_criterion("trace"), legs=FINAL, weight=2.0)
    J = np.stack([np.eye(4), 2.0 * np.eye(4)])[:, None]  # two legs, one track
    objective = Objective((InformationTerm(get_criterion("trace")), info))
    assert objective.leg_cost(J[0], 0, 2) == pytest.approx(4.0)
    assert objective.along(list(J)) == pytest.approx(4.0 + 2.0 + 2.0 * 2.0)
    assert Objective((info,)).leg_cost(J[0], 0, 2) is None


def test_bad_terms_and_aggregates_name_the_field():
    with pytest.raises(ValueError, match="terms"):
        Objective(())
    with pytest.raises(ValueError, match="legs"):
        Objective((InformationTerm(get_criterion("b_k"), legs="last"),))
    with pytest.raises(ValueError, match="weight"):
        Objective((InformationTerm(get_criterion("b_k"), weight=-1.0),))
    with pytest.raises(ValueError, match="aggregate"):
        TrackAggregate("mean")
    with pytest.raises(ValueError, match="weights"):
        TrackAggregate("weighted_sum", np.ones((2, 2)))
    with pytest.raises(ValueError, match="tie_break"):
        TrackAggregate(tie_break=-1.0)
