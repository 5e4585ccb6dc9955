"""A planner criterion registered once is usable from a scenario file (docs/extending.md).

The criterion here lives in this file only: the largest eigenvalue of the position covariance
(the squared semi-major axis of the error ellipse). Registered for PCRLB planning, MRE
positioning and MRE selection, it drives closed-loop batch runs of small scenarios that select
it by name, with no other change to the library.
"""

from pathlib import Path

import numpy as np
import pytest
import yaml

from activetrack.bounds.pcrlb import covariance_bound
from activetrack.closed_loop.batch import run_batch
from activetrack.planning import TargetBelief, plan
from activetrack.planning.criteria import (
    Criterion,
    criterion_names,
    get_criterion,
    register_criterion,
    unregister_criterion,
)
from activetrack.planning.selection import TargetPrediction, sensor_costs
from activetrack.scenarios import build_motion_model
from activetrack.scenarios.build import build_sensor, plan_settings, planner_platforms
from activetrack.scenarios.load import ScenarioError, parse_scenario

SCENARIOS = Path(__file__).parents[2] / "scenarios"
NAME = "lambda_max_pos"


def largest_position_eigenvalue(P: np.ndarray, x: np.ndarray | None = None) -> np.ndarray:
    """lambda_max of [[P(1,1), P(1,3)], [P(3,1), P(3,3)]], ``(..., 4, 4) -> (...)``."""
    block = np.asarray(P)[..., [0, 2], :][..., :, [0, 2]]
    return np.linalg.eigvalsh(block)[..., -1]


LAMBDA_MAX = Criterion(
    "lambda_max_pos",
    largest_position_eigenvalue,
    frozenset({"pcrlb", "positioning", "selection"}),
    "largest eigenvalue of the position block of P",
)


@pytest.fixture
def registered():
    register_criterion(LAMBDA_MAX)
    yield LAMBDA_MAX
    unregister_criterion(NAME)


def scenario_dict(name: str, **planner) -> dict:
    d = yaml.safe_load((SCENARIOS / f"{name}.yaml").read_text())
    d["planner"].update(planner)
    return d


def small_pcrlb(criterion: str) -> dict:
    """Hernandez sec. 5.1 (the default scenario), 4 epochs, a smaller PF."""
    d = scenario_dict("default", criterion=criterion, mc_samples=200)
    d.update(steps=4)
    d["tracker"].update(particles=1000, planner_samples=200)
    return d


def small_mre(criterion: str) -> dict:
    """Ramdaras Case 3 (positioning and selection), 6 epochs, the criterion for both."""
    d = scenario_dict("ramdaras_case3", criterion=criterion)
    d["planner"]["selection"]["criterion"] = criterion
    d.update(steps=6)
    return d


def test_an_unregistered_name_is_refused_with_the_allowed_values():
    assert NAME not in criterion_names()
    with pytest.raises(ScenarioError, match="planner.criterion: must be one of 'b_k'"):
        parse_scenario(small_pcrlb(NAME))
    with pytest.raises(ScenarioError, match="planner.selection.criterion: must be one of"):
        parse_scenario(small_mre(NAME))


def test_registration_validates_and_is_undone(registered):
    assert criterion_names("pcrlb")[-1] == NAME
    assert criterion_names("selection")[-1] == NAME
    with pytest.raises(ValueError, match="already registered"):
        register_criterion(LAMBDA_MAX)
    with pytest.raises(ValueError, match="already registered"):
        register_criterion(Criterion("b_k", LAMBDA_MAX.cost, frozenset({"pcrlb"}), ""))
    with pytest.raises(ValueError, match="needs the target state"):
        Criterion("needs_x", LAMBDA_MAX.cost, frozenset({"pcrlb"}), "", needs_state=True)
    with pytest.raises(ValueError, match="uses"):
        Criterion("nowhere", LAMBDA_MAX.cost, frozenset({"tracking"}), "")
    # The error for an unknown name now lists the registered one too.
    with pytest.raises(ScenarioError, match=f"'bearing' or '{NAME}'"):
        parse_scenario(small_pcrlb("nope"))


def test_pcrlb_planning_minimises_the_registered_criterion(registered):
    scenario = parse_scenario(small_pcrlb(NAME))
    summary = run_batch(scenario)
    decisions = summary.records[0].decisions
    assert len(decisions) == 4
    assert {d.report.criterion for d in decisions} == {NAME}
    assert np.isfinite(summary.time_avg_rmse_x[0]) and np.isfinite(summary.time_avg_bound_x[0])
    # The plan's objective is the criterion of the predicted bound J_{k+1}^{-1} (horizon 1).
    model = build_motion_model(scenario.target.motion)
    F, Q = model.transition_matrix(scenario.dt), model.process_noise(scenario.dt)
    prior = scenario.target.prior
    belief = TargetBelief.from_gaussian(
        np.array(prior.mean), prior.covariance(), 200, np.random.default_rng(3)
    )
    settings = plan_settings(scenario.planner)
    result = plan(planner_platforms(scenario), belief, settings, F=F, Q=Q, dt=scenario.dt)
    want = largest_position_eigenvalue(covariance_bound(result.J_next))
    assert result.report.objective == pytest.approx(float(want), rel=1e-12)


def test_mre_positioning_and_selection_use_the_registered_criterion(registered):
    scenario = parse_scenario(small_mre(NAME))
    record = run_batch(scenario).records[0]
    model = build_motion_model(scenario.target.motion)
    F, Q = model.transition_matrix(scenario.dt), model.process_noise(scenario.dt)
    sensors = [build_sensor(s) for p in scenario.platforms for s in p.sensors]
    carrier = [p.id for p in scenario.platforms for _ in p.sensors]
    estimate, estimate_cov = record.track_series()
    for k, d in enumerate(record.decisions):
        assert d.selection_criterion == f"mre/{NAME}" and d.report.criterion == NAME
        assert set(d.extra["positioning_costs"]) == {
            p.id for p in scenario.platforms if p.controllable
        }
        # Eq. 27 with the registered criterion: the selection costs are its values of eq. 23
        # for every sensor at its planned position, and the selection is their argmin.
        prediction = TargetPrediction.from_posterior(estimate[k], estimate_cov[k], F, Q)
        pvs = np.stack([d.extra["planned_pv"][p] for p in carrier])
        costs, P_hat = sensor_costs(prediction, sensors, pvs, NAME)
        np.testing.assert_array_equal(d.selection_costs, costs)
        np.testing.assert_array_equal(costs, largest_position_eigenvalue(P_hat))
        best = d.candidate_sensor_ids[int(np.argmin(costs))]
        assert d.selected_sensor_ids == (best,)
    assert get_criterion(NAME, "selection") is LAMBDA_MAX
