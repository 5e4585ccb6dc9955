"""The beta-cautious planner in the batch closed loop (scenarios/vanderhook_cautious.yaml):
stop-and-measure gating, Lemma 4's measurement count, Theorem 1's time bound and the c_d
stopping rule, on seeded runs."""

from pathlib import Path

import numpy as np
import pytest

from activetrack.closed_loop.loop import run_once
from activetrack.planning.cautious_bounds import (
    distance_bound,
    measurement_bound,
    time_upper_bound,
)
from activetrack.scenarios import load_scenario

SCENARIO = Path(__file__).parents[2] / "scenarios" / "vanderhook_cautious.yaml"
RUNS = 5


@pytest.fixture(scope="module")
def scenario():
    return load_scenario(SCENARIO)


@pytest.fixture(scope="module")
def records(scenario):
    return [run_once(scenario, run) for run in range(RUNS)]


def _measurement_epochs(record):
    return np.flatnonzero(record.looked[:, 0]) + 1


def test_measurements_only_after_a_full_dwell(scenario, records):
    cfg = scenario.planner.cautious
    dwell = int(np.ceil(cfg.t_m / scenario.dt))
    for r in records:
        epochs = _measurement_epochs(r)
        sigma_s = scenario.platforms[0].sensors[0].sigma
        assert 1 <= len(epochs) <= measurement_bound(cfg.beta, sigma_s, cfg.c_d, cfg.tail)  # = 4
        xy = r.platform_paths[:, 0][:, [0, 2]]
        for k in epochs:  # stood still on the spot for the t_m seconds before measuring
            np.testing.assert_allclose(xy[k - dwell : k + 1], xy[k][None].repeat(dwell + 1, 0))
        speed = np.hypot(r.platform_paths[:, 0, 1], r.platform_paths[:, 0, 3])
        assert speed.max() <= scenario.platforms[0].limits.v_max + 1e-12


def test_stops_when_both_eigenvalues_are_reduced_by_c_d(scenario, records):
    # Algorithm 1 line 4 on standard deviations: sigma(i) < c_d sigma_0(i).
    cfg = scenario.planner.cautious
    P0 = scenario.target.prior.covariance()[np.ix_([0, 2], [0, 2])]
    for r in records:
        last = _measurement_epochs(r)[-1]
        _, covs = r.track_series()
        P = covs[last][np.ix_([0, 2], [0, 2])]
        assert np.linalg.eigvalsh(P).max() <= cfg.c_d**2 * np.linalg.eigvalsh(P0).min()
        # Before the last measurement the rule was not yet met.
        before = covs[last - 1][np.ix_([0, 2], [0, 2])]
        assert np.linalg.eigvalsh(before).max() > cfg.c_d**2 * np.linalg.eigvalsh(P0).min()
        # After it the robot holds still and takes no more measurements.
        assert not r.looked[last:].any()
        assert np.ptp(r.platform_paths[last:, 0][:, [0, 2]], axis=0).max() == 0.0


def test_completion_time_below_theorem_1(scenario, records):
    cfg = scenario.planner.cautious
    sigma_s = scenario.platforms[0].sensors[0].sigma
    sigma0 = float(np.sqrt(scenario.target.prior.covariance()[0, 0]))
    n_bound = measurement_bound(cfg.beta, sigma_s, cfg.c_d, cfg.tail)
    for r in records:
        epochs = _measurement_epochs(r)
        start = r.platform_paths[0, 0][[0, 2]]
        first = r.platform_paths[epochs[0], 0][[0, 2]]
        D_A = distance_bound(sigma0, cfg.beta, sigma_s, cfg.c_d, np.hypot(*(first - start)))
        t_done = epochs[-1] * scenario.dt
        assert t_done <= time_upper_bound(n_bound, cfg.t_m, D_A)
        # and at least the dwell time of every measurement plus the drive to the first spot
        assert t_done >= len(epochs) * cfg.t_m + np.hypot(*(first - start))
