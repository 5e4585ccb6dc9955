"""Valverde reproduction (issue 7 part A): EKF MSE vs CRLB / PCRB, rank tables, scenarios."""

import itertools
import json
import math
from dataclasses import replace

import numpy as np
import pytest

from activetrack.bounds.pcrlb import covariance_bound
from activetrack.bounds.taylor_crlb import taylor_crlb
from activetrack.closed_loop.components import build_simulator, build_tracker
from activetrack.filters import ExtendedKalmanFilter, Measurement, ekf_over_runs
from activetrack.models.motion import CircularMotionKnownOmega
from activetrack.scenarios import load_scenario
from activetrack_experiments import scenario_path
from activetrack_experiments import valverde as vv

SETUP = replace(vv.ValverdeSetup(), steps=126)  # one lap
# Low, middle and high noise of Table III (sigma_r [m], sigma_b [deg]).
PAIRS = (vv.NOISE_PAIRS[0], vv.NOISE_PAIRS[3], vv.NOISE_PAIRS[6], vv.NOISE_PAIRS[10])
RUNS = 60
SCENARIOS = ("valverde_circular", "valverde_constant_turn")


@pytest.fixture(scope="module")
def results():
    return vv.reproduce(runs=RUNS, seed=3, steps=SETUP.steps, noise_pairs=PAIRS, jobs=1)


def test_reproduce_rows_and_pinned_numbers(results):
    assert (results.runs, results.seed, results.setup.steps) == (RUNS, 3, 126)
    assert [(r.case, r.model) for r in results.rows] == [
        (c, m) for c in vv.CASES for m in vv.MODELS for _ in PAIRS
    ]
    # The (1 m, 2 deg) row of each (case, model), seed 3: MSE and bound of (px, py) [m^2].
    pinned = {
        ("crlb", "circular"): (
            (0.10369129732427, 0.13239093165767),
            (0.09646834127700, 0.12700240460466),
        ),
        ("crlb", "constant_turn"): (
            (0.07144905413467, 0.11203238910196),
            (0.06927950021497, 0.10561762747797),
        ),
        ("pcrb", "circular"): (
            (0.12388992424620, 0.16948847965974),
            (0.12038117146207, 0.15108188852134),
        ),
        ("pcrb", "constant_turn"): (
            (0.10808681097586, 0.14714092492670),
            (0.10269483626593, 0.13809775784985),
        ),
    }
    for (case, model), (mse, bound) in pinned.items():
        row = results.get(case, model)[1]
        assert (row.sigma_r, row.sigma_b_deg) == (1.0, 2.0)
        np.testing.assert_allclose(row.mse, mse, rtol=1e-9)
        np.testing.assert_allclose(row.bound, bound, rtol=1e-9)
        assert row.mse_t.shape == row.bound_t.shape == (126, 2)
        np.testing.assert_allclose(row.mse_t.mean(axis=0), row.mse, rtol=1e-12)
    np.testing.assert_allclose(
        results.get("pcrb", "constant_turn")[1].bound_mc, (0.10159328, 0.13723439), rtol=1e-6
    )


def test_jobs_do_not_change_the_results():
    kw = dict(runs=4, steps=10, seed=7, noise_pairs=PAIRS[:2])
    one, two = vv.reproduce(jobs=1, **kw), vv.reproduce(jobs=2, **kw)
    assert one.to_json() == two.to_json()
    for a, b in zip(one.rows, two.rows, strict=True):
        assert np.array_equal(a.mse_t, b.mse_t) and np.array_equal(a.bound_t, b.bound_t)
    with pytest.raises(ValueError, match="jobs"):
        vv.reproduce(jobs=0, **kw)
    with pytest.raises(ValueError, match="runs"):
        vv.reproduce(runs=1, steps=10)


def test_table_has_one_flat_row_per_monte_carlo_row(results):
    table = results.table()
    assert len(table) == len(results.rows) == 2 * 2 * len(PAIRS)
    columns = set(table[0])
    assert {"case", "model", "sigma_r_m", "sigma_b_deg", "mse_x", "mse_y", "bound_x"} <= columns
    assert {"mse_se_x", "bound_mc_x", "bound_mc_y", "diverged_runs"} <= columns
    for row, r in zip(table, results.rows, strict=True):
        assert set(row) == columns
        assert (row["case"], row["model"]) == (r.case, r.model)
        assert (row["sigma_r_m"], row["sigma_b_deg"]) == (r.sigma_r, r.sigma_b_deg)
        assert (row["mse_x"], row["mse_y"]) == tuple(r.mse)
        assert (row["mse_se_x"], row["mse_se_y"]) == tuple(r.se)
        assert (row["bound_x"], row["bound_y"]) == tuple(r.bound)
        if r.bound_mc is None:
            assert math.isnan(row["bound_mc_x"]) and math.isnan(row["bound_mc_y"])
        else:
            assert (row["bound_mc_x"], row["bound_mc_y"]) == tuple(r.bound_mc)
    ranks = results.table("observability")
    assert len(ranks) == len(vv.RANK_CONDITIONS)
    assert ranks == results.to_json()["observability"]
    with pytest.raises(ValueError, match="section"):
        results.table("nope")


def test_every_mse_row_is_at_or_above_its_bound(results):
    for r in results.rows:
        assert r.diverged == 0
        assert np.all(r.se > 0)
        # At or above the bound within 3 Monte Carlo standard errors ...
        assert np.all(r.mse + 3 * r.se >= r.bound), (r.case, r.model, r.sigma_r, r.mse, r.bound)
        if r.bound_mc is not None:
            assert np.all(r.mse + 3 * r.se >= r.bound_mc)
        # ... and the EKF is close to efficient here, so the bound is not vacuous.
        assert np.all(r.mse < 1.5 * r.bound), (r.case, r.model, r.sigma_r, r.mse, r.bound)


def test_errors_and_bounds_grow_with_noise(results):
    for rows in (results.get(c, m) for c in vv.CASES for m in vv.MODELS):
        mse = np.array([r.mse for r in rows])
        bound = np.array([r.bound for r in rows])
        assert np.all(np.diff(mse, axis=0) > 0)
        assert np.all(np.diff(bound, axis=0) > 0)
    # Over all 11 Table III pairs the bound is non-decreasing (R grows in the Loewner order).
    for case in vv.CASES:
        for m in vv.MODELS:
            ix = list(vv.POSITION_INDEX[m])
            b = [
                np.diag(vv.bound_series(SETUP, m, SETUP.sensor(*p), case == "pcrb")[-1])[ix]
                for p in vv.NOISE_PAIRS
            ]
            assert np.all(np.diff(np.array(b), axis=0) >= -1e-12)


def test_time_series_is_periodic_with_the_lap():
    # Fig. 7-8: the steady-state PCRB repeats with the lap period 2 pi / omega = 125.7 s.
    setup = replace(SETUP, steps=4 * 126)
    B = vv.bound_series(setup, "constant_turn", setup.sensor(1.0, 2.0), True)[:, 0, 0]
    period = 2 * np.pi / setup.omega
    k = np.arange(300, 370)
    shifted = np.interp(k + period, np.arange(len(B)), B)
    np.testing.assert_allclose(shifted, B[k], rtol=0.03)
    assert B[k].max() > 1.5 * B[k].min()  # the pattern is visible, not flat


def test_known_rate_crlb_matches_reparametrised_model_and_is_below_circular():
    # Without process noise the constant-turn CRLB equals that of the circular model with
    # known omega (same path, Fisher information is invariant under the pv <-> (psi, p, v) map)
    # and an unknown omega (circular model) can only raise the bound on the position.
    sensor = SETUP.sensor(1.0, 2.0)
    n = 60
    paths = np.broadcast_to(SETUP.sensor_pv, (n, 1, 4))
    ct = covariance_bound(
        taylor_crlb(
            SETUP.model("constant_turn", False),
            sensor,
            paths,
            SETUP.x0("constant_turn"),
            n,
            SETUP.dt,
            P0=SETUP.P0("constant_turn"),
        )[:, 0]
    )
    keep = [0, 1, 2, 4]
    known = covariance_bound(
        taylor_crlb(
            CircularMotionKnownOmega(SETUP.omega, 0.0),
            sensor,
            paths,
            SETUP.x0("circular")[keep],
            n,
            SETUP.dt,
            P0=SETUP.P0("circular")[np.ix_(keep, keep)],
        )[:, 0]
    )
    circ = vv.bound_series(replace(SETUP, steps=n), "circular", sensor, False)
    np.testing.assert_allclose(ct[:, [0, 2], [0, 2]], known[:, [1, 2], [1, 2]], rtol=1e-6)
    assert np.all(ct[:, [0, 2], [0, 2]] <= circ[:, [1, 2], [1, 2]] * (1 + 1e-9))
    assert np.any(ct[:, 0, 0] < 0.9 * circ[:, 1, 1])


def test_rank_table_known_answers():
    rows = {
        r.condition: (r.rank_circular, r.rank_constant_turn) for r in vv.observability_table(SETUP)
    }
    # v = 0: heading and turn rate leave no trace in the measurements; px, py, v remain.
    assert rows["v = 0 (omega = 0.1 rad/s)"] == (3, 4)
    # dt -> 0: O tends to stacked copies of H (rank 2).
    assert rows["dt = 1e-12 s (dt -> 0)"] == (2, 2)
    # A straight line at 5 m/s: both models fully observable.
    assert rows["v = 5 m/s, omega = 0"] == (5, 4)
    ranks_dt = [rows[k] for k in ("dt = 1e-3 s", "dt = 1e-6 s", "dt = 1e-12 s (dt -> 0)")]
    assert all(a[0] >= b[0] and a[1] >= b[1] for a, b in itertools.pairwise(ranks_dt))
    text = vv.format_rank_tables(vv.observability_table(SETUP))
    assert "v = 5 m/s, omega = 0" in text


@pytest.mark.parametrize("model_name", vv.MODELS)
def test_ekf_over_runs_equals_the_library_ekf(model_name):
    setup = replace(SETUP, steps=40)
    model = setup.model(model_name, True)
    sensor = setup.sensor(1.0, 2.0)
    rng = np.random.default_rng(11)
    truth = vv.simulate_truth(
        model, setup.x0(model_name), setup.P0(model_name), setup.steps, setup.dt, 3, rng, True
    )
    z = vv.measure(
        sensor,
        model.kinematics(truth[1:]),
        setup.sensor_pv,
        rng.standard_normal((setup.steps, 3, 2)),
    )
    x_hat0 = np.broadcast_to(setup.x0(model_name), (3, model.dim))
    means, covs = ekf_over_runs(
        model, sensor, setup.sensor_pv, x_hat0, setup.P0(model_name), z, setup.dt
    )
    for r in range(3):
        ekf = ExtendedKalmanFilter(model, x_hat0[r], setup.P0(model_name))
        for k in range(setup.steps):
            t = (k + 1) * setup.dt
            ekf.step(t, [Measurement(sensor, setup.sensor_pv, z[k, r], t)])
            np.testing.assert_allclose(means[k, r], ekf.mean, rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(covs[k, r], ekf.cov, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("name", SCENARIOS)
def test_scenario_runs_closed_loop_with_a_consistent_ekf(name):
    scenario = load_scenario(scenario_path(name))
    assert scenario.tracker.filter == "ekf" and not scenario.planner.enabled
    assert scenario.platforms[0].sensors[0].kind == "range_bearing"
    assert not scenario.platforms[0].controllable
    sim_rng, trk_rng, _ = (np.random.default_rng(s) for s in np.random.SeedSequence(5).spawn(3))
    sim, tracker = build_simulator(scenario, sim_rng), build_tracker(scenario, trk_rng)
    nees = []
    for k in range(1, 51):
        scans = sim.advance()
        assert len(scans) == 1 and scans[0].Z.shape == (1, 2)
        (track,) = tracker.step(k, sim.time, scans).tracks
        est = tracker.model.kinematics(track.state)[[0, 2]]
        Hk = tracker.model.kinematics_jacobian(track.state)[[0, 2]]
        P_pos = Hk @ track.state_cov @ Hk.T
        np.testing.assert_allclose(track.mean[[0, 2]], est, rtol=1e-12)  # pv of the state
        e = est - sim.truth_array()[0, [0, 2]]
        nees.append(float(e @ np.linalg.solve(P_pos, e)))
    assert np.all(sim.platforms["usbl"].pv == 0.0)  # the USBL stays put
    # Position NEES is chi-square with 2 dof: mean 2, 99.9 % quantile 13.8.
    assert np.mean(nees) < 4.0
    assert max(nees) < 25.0


def test_main_prints_tables_and_writes_json_and_figures(tmp_path, capsys):
    out = tmp_path / "figs"
    argv = ["--runs", "3", "--steps", "12", "--jobs", "1"]
    rc = vv.main([*argv, "--json", str(tmp_path / "rows.json"), "--out", str(out)])
    assert rc == 0
    text = capsys.readouterr().out
    for title in ("TABLE III.", "TABLE IV.", "TABLE V.", "TABLES I-II."):
        assert title in text
    data = json.loads((tmp_path / "rows.json").read_text())
    assert len(data["rows"]) == 2 * 2 * len(vv.NOISE_PAIRS)
    assert {r["case"] for r in data["rows"]} == {"crlb", "pcrb"}
    assert len(data["observability"]) == len(vv.RANK_CONDITIONS)
    assert len(list(out.glob("fig*.png"))) == 7
    res = vv.reproduce(runs=3, steps=12)
    assert data == json.loads(json.dumps(res.to_json()))  # the CLI writes reproduce's JSON
    assert text.startswith(vv.format_report(res))
