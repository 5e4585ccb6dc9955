"""The evaluation of a run (activetrack.closed_loop.evaluation, the summary of
closed_loop.batch, activetrack.plots) on constructed records: GOSPA / OSPA closed forms,
counted breaks and swaps, RMSE of an offset track, the per-target PCRLB against the
clutter-free recursion of bounds.pcrlb and its IRF scaling."""

import math

import numpy as np
import pytest
from scipy.special import gammainc

from activetrack.bounds.pcrlb import covariance_bound, gaussian_samples, pcrlb_trajectory
from activetrack.closed_loop.batch import summarize
from activetrack.closed_loop.components import scene_sensors
from activetrack.closed_loop.evaluation import (
    NOT_HELD,
    alive_mask,
    count_breaks_swaps,
    evaluate_run,
    held_tracks,
    target_bounds,
)
from activetrack.closed_loop.record import RunRecord
from activetrack.data import Scan, ScanTruth, TrackEstimate, TrackSet
from activetrack.models.irf import information_reduction_factor
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.plots import clutter_points, plot_gospa, plot_run, track_paths
from activetrack.scenarios.build import build_sensor
from activetrack.scenarios.schema import Scenario

C = 100.0  # GOSPA / OSPA cut-off [m]
SAMPLES = 300  # bound samples (the default 1,000 is for real runs)


def make_scenario(targets, sensors=None, platforms=None, *, order=2.0, alpha=2.0, gate=3.5):
    """A validated multi-target scenario; targets: (id, mean, birth, death, q) tuples."""
    if platforms is None:
        sensor = {"id": "s1", "kind": "range_bearing", "sigma_r": 10.0, "sigma_b": 0.01}
        platforms = [{"id": "p1", "initial_state": [0.0, 0.0, -3000.0, 0.0], "sensors": sensors}]
        platforms[0]["sensors"] = sensors or [sensor]
    steps = 10
    return Scenario.model_validate(
        {
            "name": "evaluation",
            "dt": 1.0,
            "steps": steps,
            "targets": [
                {
                    "id": tid,
                    "motion": {"model": "ncv", "q": q},
                    "prior": {"mean": mean, "var": [100.0, 4.0, 100.0, 4.0]},
                    "birth": birth,
                    "death": death,
                }
                for tid, mean, birth, death, q in targets
            ],
            "platforms": platforms,
            "tracker": {"filter": "ekf", "tracks": {"gate_sigmas": gate}},
            "planner": {"enabled": False},
            "evaluation": {"cutoff": C, "order": order, "alpha": alpha},
        }
    )


def straight_truth(scenario, K):
    """(K+1, N, 4): each target from its prior mean at constant velocity, NaN off its life."""
    truth = np.full((K + 1, len(scenario.targets), 4), math.nan)
    F = NearlyConstantVelocity(q=0.0).transition_matrix(scenario.dt)
    for n, t in enumerate(scenario.targets):
        x = np.array(t.prior.mean)
        for k in range(t.birth, min(K + 1, t.death or K + 1)):
            truth[k, n] = x
            x = F @ x
    return truth


def confirmed(track_id, pv, status="confirmed", origin=""):
    pv = np.asarray(pv, dtype=float)
    return TrackEstimate(track_id, status, pv, np.eye(4), pv, np.eye(4), origin)


def make_record(scenario, truth, tracks, looked=None, platform_paths=None):
    """tracks: one list of TrackEstimate per epoch 0..K; looked ``(K, S)``: which sensors
    scanned (default: all, every epoch); every alive target observed by each scan."""
    K = truth.shape[0] - 1
    sensor_ids = tuple(s.id for p in scenario.platforms for s in p.sensors)
    if platform_paths is None:
        start = np.array([p.initial_state for p in scenario.platforms])
        platform_paths = np.repeat(start[None], K + 1, axis=0)
    if looked is None:
        looked = np.ones((K, len(sensor_ids)), dtype=bool)
    observed = np.ones((K, len(sensor_ids), truth.shape[1]), dtype=bool)
    observed &= ~np.isnan(truth[1:, None, :, 0]) & looked[:, :, None]
    return RunRecord(
        target_ids=tuple(t.id for t in scenario.targets),
        sensor_ids=sensor_ids,
        platform_ids=tuple(p.id for p in scenario.platforms),
        truth=truth,
        tracks=[
            TrackSet(k, k * scenario.dt, "ekf", tracks=tuple(ts)) for k, ts in enumerate(tracks)
        ],
        platform_paths=platform_paths,
        looked=looked,
        observed=observed,
    )


def perfect(truth, ids=None, origins="abcd"):
    """Per epoch, a confirmed track on each alive target (ids: one per target), started from
    the target's prior (``origins``: the target ids of the scenarios here)."""
    ids = ids if ids is not None else range(1, truth.shape[1] + 1)
    return [
        [
            confirmed(i, row, origin=origin)
            for i, row, origin in zip(ids, rows, origins, strict=False)
            if not np.isnan(row[0])
        ]
        for rows in truth
    ]


THREE = [
    ("a", [0.0, 5.0, 0.0, 0.0], 0, None, 0.01),
    ("b", [0.0, 5.0, 1000.0, 0.0], 0, None, 0.01),
    ("c", [0.0, 0.0, 2000.0, 5.0], 0, None, 0.01),
]


def evaluate(scenario, record, seed=0):
    return evaluate_run(scenario, record, np.random.default_rng(seed), n_samples=SAMPLES)


def sensors_by_id(scenario):
    return {sid: sensor for sid, (_, sensor) in scene_sensors(scenario).items()}


def test_perfect_tracks_give_zero_gospa_and_no_errors():
    scenario = make_scenario(THREE)
    truth = straight_truth(scenario, 10)
    ev = evaluate(scenario, make_record(scenario, truth, perfect(truth)))
    np.testing.assert_array_equal(ev.time, np.arange(1.0, 11.0))
    for series in (ev.gospa, ev.localisation, ev.missed, ev.false, ev.ospa):
        np.testing.assert_array_equal(series, 0.0)
    assert ev.mean_gospa == 0.0
    assert (ev.breaks, ev.swaps) == (0, 0)
    np.testing.assert_array_equal(ev.error, 0.0)
    np.testing.assert_array_equal(ev.held_fraction, 1.0)
    record = make_record(scenario, truth, perfect(truth))
    summary = summarize(scenario, [record], [ev])
    np.testing.assert_array_equal(summary.time_avg_rmse_x + summary.time_avg_rmse_y, 0.0)
    # The bound: the PCRLB of each target at each epoch, same draws; the summary's
    # time-averaged bound is the mean over the epochs of its standard deviation.
    B = target_bounds(scenario, record, np.random.default_rng(0), n_samples=SAMPLES)
    np.testing.assert_allclose(ev.bound, B, rtol=1e-12)
    expected = np.mean(np.sqrt(B[..., 0, 0]), axis=0)
    np.testing.assert_allclose(summary.time_avg_bound_x, expected, rtol=1e-12)
    # Targets 3, 4 and 5 km from the sensor: the cross-range (x) bound grows with range
    # (bearing 10 mrad).
    bx = summary.time_avg_bound_x
    assert bx[0] < bx[1] < bx[2]


@pytest.mark.parametrize("order", [1.0, 2.0, 3.0])
def test_one_missed_target_gives_the_closed_form(order):
    scenario = make_scenario(THREE, order=order)
    truth = straight_truth(scenario, 10)
    tracks = [ts[:2] for ts in perfect(truth)]  # target c never tracked
    ev = evaluate(scenario, make_record(scenario, truth, tracks))
    # GOSPA alpha 2: (c^p / 2)^(1/p) per missed target; OSPA: (c^p (n - m) / n)^(1/p), n = 3.
    np.testing.assert_allclose(ev.gospa, (C**order / 2) ** (1 / order), rtol=1e-12)
    np.testing.assert_allclose(ev.ospa, (C**order / 3) ** (1 / order), rtol=1e-12)
    np.testing.assert_array_equal(ev.missed, 1)
    np.testing.assert_array_equal(ev.false, 0)
    np.testing.assert_array_equal(ev.localisation, 0.0)
    assert (ev.breaks, ev.swaps) == (0, 0)
    np.testing.assert_array_equal(ev.held_fraction, [1.0, 1.0, 0.0])
    # c has no error (no track holds it) but its bound (it is alive and scanned)
    assert np.isnan(ev.error[:, 2]).all() and np.isfinite(ev.bound[:, 2]).all()
    record = make_record(scenario, truth, tracks)
    summary = summarize(scenario, [record], [ev])
    assert math.isnan(summary.time_avg_rmse_x[2]) and math.isfinite(summary.time_avg_bound_x[2])
    assert ev.mean_gospa == pytest.approx((C**order / 2) ** (1 / order), rel=1e-12)


def test_alpha_one_charges_the_full_cut_off_for_a_missed_target():
    scenario = make_scenario(THREE, alpha=1.0)
    truth = straight_truth(scenario, 10)
    ev = evaluate(scenario, make_record(scenario, truth, [ts[:2] for ts in perfect(truth)]))
    np.testing.assert_allclose(ev.gospa, C, rtol=1e-12)  # (c^p / alpha)^(1/p), alpha 1
    np.testing.assert_array_equal(ev.missed, 1)  # the split stays the alpha = 2 one


def test_a_false_track_gives_the_closed_form_and_tentative_tracks_do_not_count():
    # Clutter in the scene: the tracker starts tracks from detections (JPDA), so a track held
    # by no target can be there. Known association has the target's track alone (below).
    sensor = {"id": "s1", "kind": "range_bearing", "sigma_r": 10.0, "sigma_b": 0.01}
    scenario = make_scenario(THREE[:1], [{**sensor, "r_max": 9000.0, "clutter_density": 1e-4}])
    truth = straight_truth(scenario, 10)
    tracks = [
        [*ts, confirmed(9, [5000.0, 0, 5000.0, 0]), confirmed(8, [-900.0, 0, 0, 0], "tentative")]
        for ts in perfect(truth)
    ]
    ev = evaluate(scenario, make_record(scenario, truth, tracks))
    np.testing.assert_allclose(ev.gospa, math.sqrt(C**2 / 2), rtol=1e-12)  # 70.71 m
    np.testing.assert_allclose(ev.ospa, math.sqrt(C**2 / 2), rtol=1e-12)  # n = 2, m = 1
    np.testing.assert_array_equal(ev.false, 1)
    np.testing.assert_array_equal(ev.missed, 0)
    assert (ev.breaks, ev.swaps) == (0, 0)


def test_a_withheld_track_is_not_scored_a_held_target_then_counts_missed():
    """GOSPA scores the tracker's estimate: a confirmed track it withholds (report: gospa)
    counts neither as a false track nor as holding its target."""
    from dataclasses import replace

    sensor = {"id": "s1", "kind": "range_bearing", "sigma_r": 10.0, "sigma_b": 0.01}
    scenario = make_scenario(THREE[:1], [{**sensor, "r_max": 9000.0, "clutter_density": 1e-4}])
    truth = straight_truth(scenario, 10)
    false = confirmed(9, [5000.0, 0, 5000.0, 0])
    shown = [[*ts, false] for ts in perfect(truth)]
    hidden = [[replace(t, withheld=True) for t in ts] for ts in shown]
    shown = evaluate(scenario, make_record(scenario, truth, shown))
    ev = evaluate(scenario, make_record(scenario, truth, hidden))
    np.testing.assert_array_equal(shown.false, 1)
    np.testing.assert_array_equal(shown.missed, 0)
    np.testing.assert_array_equal(ev.false, 0)
    np.testing.assert_array_equal(ev.missed, 1)  # the target's own track withheld
    np.testing.assert_allclose(ev.gospa, math.sqrt(C**2 / 2), rtol=1e-12)
    assert (ev.held == -1).all() and np.isnan(ev.error).all()


def test_a_constant_offset_track_has_that_rmse():
    scenario = make_scenario(THREE[:1])
    truth = straight_truth(scenario, 10)
    offset = np.array([6.0, 0.0, -8.0, 0.0])  # 10 m
    tracks = [[confirmed(1, row[0] + offset, origin="a")] for row in truth]
    record = make_record(scenario, truth, tracks)
    ev = evaluate(scenario, record)
    np.testing.assert_allclose(ev.error[:, 0], np.tile(offset, (10, 1)), atol=1e-9)
    summary = summarize(scenario, [record], [ev])
    rmse = (summary.time_avg_rmse_x[0], summary.time_avg_rmse_y[0])
    assert rmse == pytest.approx((6.0, 8.0), rel=1e-12)
    assert math.hypot(*rmse) == pytest.approx(10.0, rel=1e-12)
    np.testing.assert_allclose(ev.gospa, 10.0, rtol=1e-12)
    np.testing.assert_allclose(ev.ospa, 10.0, rtol=1e-12)
    np.testing.assert_allclose(ev.localisation, 100.0, rtol=1e-12)  # d^p, p = 2


def test_an_exchange_of_targets_is_two_swaps_and_invisible_to_gospa():
    scenario = make_scenario(THREE[:2])
    truth = straight_truth(scenario, 10)
    tracks = perfect(truth[:5]) + perfect(truth[5:], ids=[2, 1])  # tracks 1, 2 exchange at k=5
    record = make_record(scenario, truth, tracks)
    ev = evaluate(scenario, record)
    assert (ev.swaps, ev.breaks) == (2, 0)
    np.testing.assert_array_equal(ev.gospa, 0.0)
    held = held_tracks(scenario, record)
    np.testing.assert_array_equal(held[:4], [[1, 2]] * 4)  # epochs 1..4
    np.testing.assert_array_equal(held[4:], [[2, 1]] * 6)  # epochs 5..10


def test_breaks_and_swaps_counted_exactly():
    targets = [
        ("a", [0.0, 5.0, 0.0, 0.0], 0, None, 0.01),
        ("b", [0.0, 5.0, 1000.0, 0.0], 0, 6, 0.01),  # dies at epoch 6: not a break
        ("c", [0.0, 0.0, 2000.0, 5.0], 0, None, 0.01),
        ("d", [3000.0, 0.0, 0.0, -5.0], 0, None, 0.01),
    ]
    scenario = make_scenario(targets)
    truth = straight_truth(scenario, 8)
    far = np.array([500.0, 0.0, 0.0, 0.0])  # beyond the cut-off
    tracks = []
    for k, (a, b, c, d) in enumerate(truth):
        ts = []
        if k <= 3 or k >= 6:  # a: lost at 4 and 5 (one break), new track 7 from 6 (no swap)
            ts.append(confirmed(1 if k <= 3 else 7, a))
        ts.append(confirmed(2, b if k < 6 else b_last(truth)))  # b's track outlives b
        ts.append(confirmed(3, c + far if k == 2 else c))  # c: off at 2 (a break), back at 3
        ts.append(confirmed(4 if k < 4 else 5, d))  # d: track 4 replaced by 5 at 4 (a swap)
        tracks.append(ts)
    record = make_record(scenario, truth, tracks)
    ev = evaluate(scenario, record)
    assert (ev.breaks, ev.swaps) == (2, 1)
    # a held at 1-3 and 6-8 of its 8 epochs; b at all 5 it lived (1-5); c all but epoch 2.
    np.testing.assert_allclose(ev.held_fraction, [0.75, 1.0, 7 / 8, 1.0], rtol=1e-12)
    held = held_tracks(scenario, record)
    np.testing.assert_array_equal(held[:, 0], [1, 1, 1, NOT_HELD, NOT_HELD, 7, 7, 7])
    np.testing.assert_array_equal(held[:, 2], [3, NOT_HELD, 3, 3, 3, 3, 3, 3])


def b_last(truth):
    return truth[5, 1] + np.array([25.0, 0.0, 0.0, 0.0])


def test_count_breaks_swaps_on_a_table():
    H = NOT_HELD
    held = np.array([[1, 2, H], [1, 3, 4], [H, 3, 4], [H, H, 5], [6, H, 5]])
    alive = np.array([[1, 1, 1], [1, 1, 1], [1, 1, 1], [1, 0, 1], [1, 0, 1]], dtype=bool)
    # column 0: break at 2; column 1: swap at 1, then death (no break); column 2: swap at 3.
    assert count_breaks_swaps(held, alive) == (1, 2)
    with pytest.raises(ValueError, match="held and alive"):
        count_breaks_swaps(held, alive[:, :2])


# --- the per-target bound ----------------------------------------------------------------------


def two_sensor_scenario(clutter=0.0, pd=1.0, gate=10.0, q=0.01, fov_width=None):
    sensors_1 = [
        {"id": "b1", "kind": "bearing", "sigma": 0.01, "pd": pd, "clutter_density": clutter}
    ]
    if fov_width is not None:
        sensors_1[0] |= {"fov_width": fov_width, "fov_centre": 3.0}
    sensors_2 = [{"id": "rb", "kind": "range_bearing", "sigma_r": 20.0, "sigma_b": 0.02}]
    platforms = [
        {"id": "p1", "initial_state": [-2000.0, 0.0, 0.0, 0.0], "sensors": sensors_1},
        {"id": "p2", "initial_state": [0.0, 0.0, -2500.0, 0.0], "sensors": sensors_2},
    ]
    target = ("a", [0.0, 3.0, 0.0, -2.0], 0, None, q)
    return make_scenario([target], platforms=platforms, gate=gate)


def moving_paths(scenario, K):
    """(K+1, 2, 4): platform 1 moving north at 15 m/s, platform 2 still."""
    paths = np.repeat(np.array([p.initial_state for p in scenario.platforms])[None], K + 1, 0)
    paths[:, 0, 3] = 15.0
    paths[:, 0, 2] = 15.0 * np.arange(K + 1)
    return paths


def looks(K):
    """(K, 2): a fixed pattern of looks (sensor 1 every epoch but 3 and 4, sensor 2 odd k)."""
    looked = np.ones((K, 2), dtype=bool)
    looked[[2, 3], 0] = False
    looked[1::2, 1] = False
    return looked


def bound_record(scenario, K=10, looked=None):
    truth = straight_truth(scenario, K)
    looked = looks(K) if looked is None else looked
    return make_record(scenario, truth, perfect(truth), looked, moving_paths(scenario, K))


@pytest.mark.parametrize("fov_width", [None, 0.5])
def test_without_clutter_the_bound_is_the_pcrlb_recursion(fov_width):
    # pd 1, no clutter, one target: known association, q = pd = 1, so the bound is Hernandez
    # eq. 3 with eq. 8-9 (bounds.pcrlb) over the same samples with the sensors that scanned
    # (record.looked). A fixed field of view acts through the samples: pointed away from the
    # target (0.5 rad wide, 3 rad off the platform's heading north; the target is east), the
    # bearing sensor adds nothing, as if it had never scanned.
    scenario = two_sensor_scenario(fov_width=fov_width)
    record = bound_record(scenario)
    B = target_bounds(scenario, record, np.random.default_rng(7), n_samples=SAMPLES)
    rng = np.random.default_rng(7)
    target = scenario.targets[0]
    model = NearlyConstantVelocity(q=0.01)
    F, Q = model.transition_matrix(1.0), model.process_noise(1.0)
    C0 = target.prior.covariance()
    X0 = gaussian_samples(np.array(target.prior.mean), C0, SAMPLES, rng)
    sensors = [build_sensor(s) for p in scenario.platforms for s in p.sensors]
    J = pcrlb_trajectory(
        np.linalg.inv(C0),
        F,
        Q,
        X0,
        sensors,
        record.platform_paths[1:],
        rng,
        active=record.looked & [fov_width is None, True],
    )
    np.testing.assert_allclose(B[:, 0], covariance_bound(J), rtol=1e-6)
    # The looks matter: without those of epochs 3 and 4 the position bound grows there.
    assert fov_width is not None or B[3, 0, 0, 0] > B[1, 0, 0, 0]


def test_clutter_scales_the_measurement_information_by_the_irf_ratio():
    # Q = 0: J_k = T_k(J_0) + sum_j T_kj(q J_Z,j) is linear in the measurement terms, so the
    # information they add scales exactly by q_clutter / q_free (same samples, same looks).
    # Without clutter one target is tracked by known association (no gate): q_free = pd.
    lam = 10.0  # false alarms per rad: 63 per scan all around, 0.1 per sigma of bearing
    K = 10
    bounds = {}
    for name, (clutter, looked) in {
        "free": (0.0, looks(K)),
        "clutter": (lam, looks(K)),
        "none": (0.0, np.zeros((K, 2), dtype=bool)),
    }.items():
        scenario = two_sensor_scenario(clutter=clutter, pd=0.9, gate=3.5, q=0.0)
        record = bound_record(scenario, K, looked)
        bounds[name] = target_bounds(scenario, record, np.random.default_rng(3), n_samples=SAMPLES)
    J = {name: np.linalg.inv(B[:, 0]) for name, B in bounds.items()}
    q_gated = information_reduction_factor(0.9, 0.0, 3.5, 1)
    q_clutter = information_reduction_factor(0.9, lam * 0.01, 3.5, 1)  # lambda sqrt(det R)
    assert q_gated == pytest.approx(0.9 * gammainc(1.5, 3.5**2 / 2), abs=1e-12)  # Pd F_chi2,3
    assert q_clutter / q_gated == pytest.approx(0.656, abs=1e-3)
    q_free = scene_sensors(two_sensor_scenario(pd=0.9, gate=3.5))["b1"][1].information_factor
    assert q_free == 0.9
    # Only the bearing sensor sees clutter, but with clutter in the scene the tracker gates
    # every sensor's detections (JPDA), so the range-bearing sensor's factor is its gate's:
    # q_rb = F_{chi2, 4}(3.5^2) (pd 1). Split the two sensors' shares with one-sensor
    # versions of the same looks.
    q_rb = scene_sensors(two_sensor_scenario(clutter=lam, gate=3.5))["rb"][1].information_factor
    assert q_rb == pytest.approx(information_reduction_factor(1.0, 0.0, 3.5, 2), rel=1e-12)
    assert q_rb == pytest.approx(0.98441, abs=1e-5)
    shares = {}
    for sensor in (0, 1):
        alone = looks(K)
        alone[:, 1 - sensor] = False
        for clutter in (0.0, lam):
            scenario = two_sensor_scenario(clutter=clutter, pd=0.9, gate=3.5, q=0.0)
            record = bound_record(scenario, K, alone)
            B = target_bounds(scenario, record, np.random.default_rng(3), n_samples=SAMPLES)
            shares[sensor, clutter] = np.linalg.inv(B[:, 0]) - J["none"]
    ratio = q_clutter / q_free
    np.testing.assert_allclose(shares[0, lam], ratio * shares[0, 0.0], rtol=1e-6, atol=1e-12)
    np.testing.assert_allclose(shares[1, lam], q_rb * shares[1, 0.0], rtol=1e-6, atol=1e-12)
    added = J["clutter"] - J["free"]  # each sensor's share scaled by its factor
    expected = (ratio - 1.0) * shares[0, 0.0] + (q_rb - 1.0) * shares[1, 0.0]
    np.testing.assert_allclose(added, expected, rtol=1e-6, atol=1e-12)
    pos = {name: B[:, 0, 0, 0] + B[:, 0, 2, 2] for name, B in bounds.items()}
    assert np.all(pos["clutter"] > pos["free"]) and np.all(pos["clutter"] < pos["none"])


def test_a_target_born_later_starts_from_its_prior_and_ends_at_death():
    targets = [
        ("a", [0.0, 5.0, 0.0, 0.0], 0, None, 0.01),
        ("late", [0.0, 5.0, 1000.0, 0.0], 3, 7, 0.5),
    ]
    scenario = make_scenario(targets)
    truth = straight_truth(scenario, 10)
    looked = np.zeros((10, 1), dtype=bool)  # no scan: the bound is the prior's prediction
    record = make_record(scenario, truth, perfect(truth), looked)
    B = target_bounds(scenario, record, np.random.default_rng(1), n_samples=SAMPLES)
    C0 = scenario.targets[1].prior.covariance()
    model = NearlyConstantVelocity(q=0.5)
    F, Q = model.transition_matrix(1.0), model.process_noise(1.0)
    assert np.isnan(B[[0, 1, 7, 8, 9], 1]).all()  # alive at epochs 3..6 only
    np.testing.assert_allclose(B[2, 1], C0, rtol=1e-12)  # epoch 3 = birth
    np.testing.assert_allclose(B[3, 1], F @ C0 @ F.T + Q, rtol=1e-12)
    assert np.isfinite(B[:, 0]).all()
    # Looked at on its birth epoch: J_b = C0^-1 + J_Z(b), below the prior.
    record = make_record(scenario, truth, perfect(truth))
    B = target_bounds(scenario, record, np.random.default_rng(1), n_samples=SAMPLES)
    assert np.trace(B[2, 1]) < np.trace(C0)


def test_records_that_do_not_fit_the_scenario_are_rejected():
    scenario = make_scenario(THREE[:2])
    truth = straight_truth(scenario, 10)
    record = make_record(scenario, truth, perfect(truth))
    bad = np.array(truth)
    bad[4, 1] = math.nan  # target b missing mid-life
    with pytest.raises(ValueError, match="record.truth"):
        alive_mask(scenario, make_record(scenario, bad, perfect(truth)))
    record.target_ids = ("b", "a")
    with pytest.raises(ValueError, match="record.target_ids"):
        evaluate(scenario, record)
    for name in ("looked", "observed"):
        record = make_record(scenario, truth, perfect(truth))
        setattr(record, name, None)
        with pytest.raises(ValueError, match=f"record.{name}"):
            target_bounds(scenario, record, np.random.default_rng(0))
    record = make_record(scenario, truth, perfect(truth)[:-1])
    with pytest.raises(ValueError, match="record.tracks"):
        evaluate(scenario, record)
    # One target without clutter (known association): every track is the target's.
    one = make_scenario(THREE[:1])
    truth = straight_truth(one, 10)
    tracks = [[*ts, confirmed(9, [5000.0, 0, 5000.0, 0])] for ts in perfect(truth)]
    with pytest.raises(ValueError, match=r"record.tracks\[1\]: track 9 has origin ''"):
        evaluate(one, make_record(one, truth, tracks))


# --- plots -------------------------------------------------------------------------------------


def with_scans(scenario, record):
    """Add one range-bearing scan per epoch: a target detection and two clutter points."""
    for k in range(1, record.truth.shape[0]):
        pv = record.platform_paths[k, 0]
        Z = np.array([[100.0, math.pi / 2], [3000.0, 1.0], [200.0, 0.0]])
        record.scans.append([Scan("s1", k, float(k), pv, Z)])
        record.scan_truth.append([ScanTruth("s1", k, ("", "a", ""))])
    return record


def test_clutter_points_and_track_paths():
    scenario = make_scenario(THREE[:1])
    truth = straight_truth(scenario, 3)
    tracks = perfect(truth)
    tracks[2] = []  # track 1 unconfirmed at epoch 2: a gap in its path
    record = with_scans(scenario, make_record(scenario, truth, tracks))
    xy = clutter_points(sensors_by_id(scenario), record)  # sensor at (0, -3000)
    np.testing.assert_allclose(xy, [[0.0, -2900.0], [200.0, -3000.0]] * 3, atol=1e-9)
    paths = track_paths(record)
    assert list(paths) == [1]
    assert np.isnan(paths[1][2]).all()
    np.testing.assert_array_equal(paths[1][3], truth[3, 0, [0, 2]])


def test_plots_write_non_empty_files(tmp_path):
    scenario = make_scenario(THREE)
    truth = straight_truth(scenario, 10)
    record = with_scans(scenario, make_record(scenario, truth, perfect(truth)))
    out = plot_run(scenario.name, sensors_by_id(scenario), record, tmp_path / "run.png")
    assert out.stat().st_size > 10_000
    evs = [evaluate(scenario, record, seed) for seed in range(2)]
    missed = [evaluate(scenario, make_record(scenario, truth, [ts[:2] for ts in perfect(truth)]))]
    out = plot_gospa({"perfect": evs, "missed c": missed}, tmp_path / "gospa.png")
    assert out.stat().st_size > 10_000
    with pytest.raises(ValueError, match="evaluations"):
        plot_gospa({"none": []}, tmp_path / "x.png")
