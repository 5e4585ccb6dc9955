"""Planning across targets (issue 14 sec. 4): manoeuvres against every confirmed track, beams
assigned to tracks, multi-step MRE positioning.

- the aggregate matters: in a two-track geometry "worst" turns towards the uncertain track,
  "weighted_sum" (priority 50 on the other) towards the other one;
- the optimal beam assignment equals brute force over all assignments (cost matrices with
  ties, and the MRE costs of random geometries);
- with one track the planner is the single-target one: PCRLB plan() (R = 1, 2 quadrant, R = 3
  evolution) and MRE positioning (R = 1, 2) with a sensor whose pd is the IRF q;
- clutter: a bearing sensor's predicted information is q times the clutter-free one; a beam
  informs only its track; no confirmed track: beams sweep; random assignment is seeded;
- a beam that found nothing at a track lowers the probability that the next one holds it
  (Bayes' rule against Monte Carlo), so beams leave a track lost to the tracker.
"""

import dataclasses
import itertools
import math

import numpy as np
import pytest

from activetrack.angles import wrap_angle
from activetrack.bounds.mre import mre_update
from activetrack.bounds.pcrlb import covariance_bound, predicted_information, propagate_samples
from activetrack.closed_loop.components import build_across_targets, target_dynamics
from activetrack.data import PlatformSnapshot, TrackEstimate, TrackSet, heading_speed
from activetrack.models.clutter import ClutteredSensor
from activetrack.models.fov import sector_coverage
from activetrack.models.irf import IRF_TABLE_TOLERANCE, information_reduction_factor
from activetrack.models.sensors import BearingSensor, RangeBearingSensor, RangeRateBearingSensor
from activetrack.planning.assignment import (
    NO_MISSES,
    MissedLooks,
    assign_beams,
    assignment_value,
    beam_candidates,
    beam_coverage,
    coverage_after_misses,
    footprint_pointing,
    joint_coverage,
    mre_pair_costs,
    random_assignment,
    round_assignment,
)
from activetrack.planning.criteria import get_criterion
from activetrack.planning.horizons import SearchSettings
from activetrack.planning.objective import aggregate_costs
from activetrack.planning.planner import PlannerPlatform, TargetBelief, plan
from activetrack.planning.selection import TargetPrediction, expected_update, plan_positions
from activetrack.scenarios import parse_scenario
from activetrack.scenarios.build import plan_settings, platform_limits

LIMITS = {"dpsi_max": 0.6, "dv_max": 10.0, "v_min": 30.0, "v_max": 120.0}
TARGET = {
    "id": "t1",
    "motion": {"model": "ncv", "q": 0.01},
    "prior": {"mean": [1000.0, 1.0, 1000.0, 1.0], "var": [100.0, 1.0, 100.0, 1.0]},
}


def scenario(platforms, planner=None, gate=3.5):
    data = {
        "name": "mt_test",
        "dt": 5.0,
        "steps": 10,
        "targets": [TARGET],
        "platforms": platforms,
        "tracker": {"filter": "ekf", "tracks": {"gate_sigmas": gate}},
        "planner": planner or {},
    }
    return parse_scenario(data, "mt_test")


def platform(pid, pv, sensors, controllable=False):
    out = {"id": pid, "initial_state": list(pv), "sensors": sensors}
    return {**out, "controllable": True, "limits": LIMITS} if controllable else out


def snapshots(sc):
    out = []
    for p in sc.platforms:
        pv = np.array(p.initial_state)
        out.append(PlatformSnapshot(p.id, 0, 0.0, pv, *heading_speed(pv)))
    return out


def track(i, mean, cov, status="confirmed", priority=1.0, samples=None):
    m, P = np.asarray(mean, float), np.asarray(cov, float)
    return TrackEstimate(i, status, m, P, m, P, priority=priority, samples=samples)


def decide(sc, tracks, seed=0, epoch=0):
    planner = build_across_targets(sc, np.random.default_rng(seed))
    return planner.plan(epoch, TrackSet(epoch, 0.0, "ekf", tracks=tuple(tracks)), snapshots(sc))


# --- the aggregate ----------------------------------------------------------------------------


def test_worst_and_weighted_sum_choose_differently():
    # One platform at the origin heading +x with an all-around bearing sensor; track 1 to the
    # north-east with sigma 200 m, track 2 to the south-east with sigma 100 m and priority 50.
    sensor = {"id": "s1", "kind": "bearing", "sigma": 0.02}
    platforms = [platform("p1", [0.0, 50.0, 0.0, 0.0], [sensor], controllable=True)]
    tracks = [
        track(1, [3000, 0, 3000, 0], np.diag([4e4, 4, 4e4, 4])),
        track(2, [3000, 0, -3000, 0], np.diag([1e4, 4, 1e4, 4]), priority=50.0),
    ]
    out = {}
    for aggregate in ("worst", "weighted_sum"):
        planner = {"search": "grid", "grid_size": 11, "mc_samples": 300}
        sc = scenario(platforms, {**planner, "targets": {"aggregate": aggregate}})
        d = decide(sc, tracks)
        costs = d.extra["track_costs"]
        assert d.report.cost_names[:4] == ("aggregate", "objective", "track_1", "track_2")
        weights = [1.0, 50.0]
        want = aggregate_costs([costs[1], costs[2]], weights, aggregate)
        assert d.report.predicted_costs[0] == pytest.approx(want, rel=1e-12)
        out[aggregate] = (d.commands[0].heading_change, costs[1], costs[2])
    # worst: hard left towards track 1, b_k 151.0 / 86.1 m; weighted_sum: hard right towards
    # track 2, 158.4 / 84.1 m (50 x 2.0 m gained on track 2 against 7.4 m lost on track 1).
    assert out["worst"][0] == pytest.approx(0.6)
    assert out["weighted_sum"][0] == pytest.approx(-0.6)
    assert out["worst"][1] == pytest.approx(151.0, abs=0.1)
    assert out["weighted_sum"][1:] == pytest.approx((158.4, 84.1), abs=0.1)
    assert out["worst"][1] < out["weighted_sum"][1] and out["worst"][2] > out["weighted_sum"][2]


# --- the assignment ---------------------------------------------------------------------------


def _brute_force(C, c0, w, aggregate):
    S, T = C.shape
    return min(
        assignment_value(p, C, c0, w, aggregate) for p in itertools.permutations(range(T), S)
    )


def test_round_assignment_equals_brute_force_on_random_cost_matrices():
    rng = np.random.default_rng(0)
    for case in range(400):
        S = int(rng.integers(1, 4))
        T = int(rng.integers(S, 6))
        c0 = rng.uniform(1.0, 10.0, T)
        C = c0 * rng.uniform(0.2, 1.0, (S, T))
        if case % 3 == 0:  # integer costs: many ties, for "worst" in particular
            C = np.round(C)
            c0 = np.maximum(np.round(c0), C.max(axis=0))
        w = rng.uniform(0.5, 3.0, T)
        for aggregate in ("worst", "weighted_sum"):
            picks = round_assignment(C, c0, w, aggregate)
            assert sorted(set(picks.tolist())) == sorted(picks.tolist()) and picks.min() >= 0
            value = assignment_value(picks, C, c0, w, aggregate)
            assert value == pytest.approx(_brute_force(C, c0, w, aggregate), rel=1e-12)


def _random_geometry(rng, S, T):
    F = np.array([[1.0, 1.0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 1.0], [0, 0, 0, 1.0]])
    Q = np.diag([0.25, 1.0, 0.25, 1.0])
    predictions = []
    for _ in range(T):
        x = np.array([rng.uniform(0, 8000), rng.uniform(-50, 50)] * 2)
        x[2], x[3] = rng.uniform(0, 8000), rng.uniform(-50, 50)
        predictions.append(TargetPrediction(x, np.diag(rng.uniform(100, 5000, 4)), F, Q))
    kinds = [
        BearingSensor(0.002, pd=0.9),
        RangeBearingSensor(30.0, 0.002, pd=0.8),
        RangeRateBearingSensor(8.0, 10.0, 0.02, pd=0.7),
    ]
    sensors = [kinds[int(rng.integers(3))] for _ in range(S)]
    pvs = np.column_stack([rng.uniform(-2000, 10000, S), np.zeros(S)] * 2)
    pvs[:, 2] = rng.uniform(-2000, 10000, S)
    return predictions, sensors, pvs, rng.uniform(0.5, 1.0, (S, T))


def test_mre_beam_assignment_equals_brute_force_on_random_geometries():
    rng = np.random.default_rng(7)
    crit = get_criterion("det_pos")
    for _ in range(12):
        S = int(rng.integers(1, 4))
        T = int(rng.integers(S, 5))
        preds, sensors, pvs, d = _random_geometry(rng, S, T)
        w = rng.uniform(0.5, 3.0, T)

        def value(tracks_of, aggregate, preds=preds, sensors=sensors, pvs=pvs, d=d, w=w):
            costs = []
            for t, p in enumerate(preds):
                mine = [s for s in range(len(sensors)) if tracks_of[s] == t]
                P = expected_update(
                    p.P, p.x, [sensors[s] for s in mine], pvs[mine], detection=d[mine, t]
                )
                costs.append(float(crit.of_covariance(p.F @ P @ p.F.T + p.Q, p.x)))
            return float(aggregate_costs(costs, w, aggregate))

        for aggregate in ("worst", "weighted_sum"):
            picks = assign_beams(preds, sensors, pvs, d, "det_pos", w, aggregate)
            best = min(value(p, aggregate) for p in itertools.permutations(range(T), S))
            assert value(picks, aggregate) == pytest.approx(best, rel=1e-12)


def _costs(preds, sensors, pvs, d):
    return mre_pair_costs(preds, sensors, pvs, d, "det_pos")


def test_more_beams_than_tracks_share_them_in_rounds():
    rng = np.random.default_rng(5)
    preds, sensors, pvs, d = _random_geometry(rng, 3, 2)
    w = np.ones(2)
    picks = assign_beams(preds, sensors, pvs, d, "det_pos", w, "weighted_sum")
    assert sorted(picks.tolist()) in ([0, 0, 1], [0, 1, 1])  # every track served
    first = round_assignment(*_costs(preds, sensors, pvs, d), w, "weighted_sum")
    waiting = int(np.flatnonzero(first < 0)[0])
    assert picks[first >= 0].tolist() == first[first >= 0].tolist()
    # The waiting sensor joins the track where it then gains most (round 2, after round 1).
    gains = []
    for t, p in enumerate(preds):
        s = int(np.flatnonzero(first == t)[0])
        P = expected_update(p.P, p.x, [sensors[s]], pvs[s], detection=d[s, t : t + 1])
        C, c0 = _costs(
            [p.with_covariance(P)], [sensors[waiting]], pvs[[waiting]], d[[waiting]][:, [t]]
        )
        gains.append(C[0, 0] - c0[0])
    assert picks[waiting] == int(np.argmin(gains))


def test_beam_coverage_is_the_probability_the_beam_holds_the_target():
    # A target N(x, P) 4 km away, 300 m across the line of sight (0.075 rad), a 0.1 rad beam
    # pointed at x: erf(0.05 / (sqrt 2 0.075)) = 0.495; Monte Carlo of the true bearings.
    x, pv = np.array([4000.0, 5.0, 0.0, 0.0]), np.array([0.0, 10.0, 0.0, 0.0])
    P = np.diag([100.0**2, 4.0, 300.0**2, 4.0])
    got = float(beam_coverage(0.1, x, P, pv))
    assert got == pytest.approx(math.erf(0.05 / (math.sqrt(2.0) * 0.075)), rel=1e-9)
    X = np.random.default_rng(1).multivariate_normal(x, P, 200_000)
    inside = np.abs(np.arctan2(X[:, 2], X[:, 0])) <= 0.05
    assert got == pytest.approx(0.495, abs=1e-3)
    # 4 sigma of the Monte Carlo and 0.005 for the linearised bearing (300 m at 4 km).
    tolerance = 4 * math.sqrt(got * (1 - got) / 200_000) + 0.005
    assert inside.mean() == pytest.approx(got, abs=tolerance)
    # Batched over sensor positions: closer, the same spread is wider in angle.
    near = beam_coverage(0.1, x, P, np.array([pv, [3000.0, 0.0, 0.0, 0.0]]))
    assert near[0] == pytest.approx(got) and near[1] < 0.2


def test_coverage_after_misses_is_bayes_rule_for_unsuccessful_looks():
    # c = 0.6, pd 0.8: one miss 0.12 / 0.52 = 0.2308, two 0.024 / 0.424 = 0.0566.
    c, pd = 0.6, 0.8
    got = coverage_after_misses(c, [1.0, 1 - pd, (1 - pd) ** 2])
    assert got == pytest.approx([0.6, 0.2308, 0.0566], abs=1e-4)
    assert coverage_after_misses([0.0, 1.0], 0.5) == pytest.approx([0.0, 1.0])
    assert coverage_after_misses(1.0, 0.0) == 0.0  # 0 / 0: a certain miss says "not there"
    # Monte Carlo: the target is in the beam with probability c, each look detects it with pd
    # when it is; among the runs with two misses, the fraction in the beam (4 sigma).
    rng = np.random.default_rng(11)
    n = 400_000
    inside = rng.random(n) < c
    missed = ~(inside[:, None] & (rng.random((n, 2)) < pd)).any(axis=1)
    frac = inside[missed].mean()
    tol = 4 * math.sqrt(got[2] * (1 - got[2]) / missed.sum())
    assert frac == pytest.approx(got[2], abs=tol)
    with pytest.raises(ValueError, match="miss_factor"):
        coverage_after_misses(0.5, 1.5)


def test_joint_coverage_is_the_bivariate_normal_rectangle():
    # P(|U| < t1, |V| < t2), corr rho, against scipy's bivariate normal cdf (4 corners).
    from scipy.special import erfinv
    from scipy.stats import multivariate_normal

    for c1, c2, rho in [(0.6, 0.3, 0.5), (0.9, 0.95, 0.99), (0.2, 0.8, 0.1), (0.3, 0.3, 0.9)]:
        t1, t2 = math.sqrt(2) * erfinv(c1), math.sqrt(2) * erfinv(c2)
        mvn = multivariate_normal(mean=[0.0, 0.0], cov=[[1.0, rho], [rho, 1.0]])
        want = mvn.cdf([t1, t2]) - mvn.cdf([-t1, t2]) - mvn.cdf([t1, -t2]) + mvn.cdf([-t1, -t2])
        assert float(joint_coverage(c1, c2, rho)) == pytest.approx(want, abs=1e-7)
    # rho 1: the same offsets (the smaller interval); rho 0: independent; edges.
    got = joint_coverage([0.5, 0.5, 0.5, 0.0, 1.0], [0.3, 0.8, 0.8, 0.5, 0.4], [1, 1, 0, 0.5, 0.5])
    assert got == pytest.approx([0.3, 0.5, 0.4, 0.0, 0.4], abs=1e-12)
    with pytest.raises(ValueError, match="rho"):
        joint_coverage(0.5, 0.5, 1.5)


def test_misses_say_less_as_the_prediction_widens():
    # One look missed (pd 0.8) a beam holding c1 = 0.6 of the prediction then; now the
    # prediction is wider (offsets a random walk: corr rho = sigma_then / sigma_now) and the
    # beam holds c2 = 0.35 of it. Same beam: Bayes' rule as before; rho 0: the look says
    # nothing; in between, Monte Carlo over the walk (4 sigma).
    from scipy.special import erfinv

    pd, c1, c2 = 0.8, 0.6, 0.35
    assert coverage_after_misses(c1, 0.2, c1, 1.0) == pytest.approx(coverage_after_misses(c1, 0.2))
    assert coverage_after_misses(c2, 0.2, c1, 0.0) == pytest.approx(c2)
    rho = 0.5
    got = float(coverage_after_misses(c2, 1 - pd, c1, rho))
    rng = np.random.default_rng(5)
    n = 400_000
    u = rng.standard_normal(n)
    v = rho * u + math.sqrt(1 - rho**2) * rng.standard_normal(n)  # standardised offset now
    t1, t2 = (math.sqrt(2) * float(erfinv(c)) for c in (c1, c2))
    missed = ~((np.abs(u) < t1) & (rng.random(n) < pd))
    frac = (np.abs(v[missed]) < t2).mean()
    assert frac == pytest.approx(got, abs=4 * math.sqrt(got * (1 - got) / missed.sum()))
    assert coverage_after_misses(c2, 0.2) < got < c2  # less sure than the same beam's rule
    # MissedLooks: the correlation from the spreads, a prediction no wider: the same beam.
    P = np.diag([400.0, 1.0, 500.0, 1.0])
    looks = MissedLooks(0.2, c1, 225.0)  # spread then 225 m^2, now 900: rho 0.5
    assert float(looks.after(c2, P)) == pytest.approx(got, rel=1e-12)
    assert float(MissedLooks(0.2, c1, 900.0).after(c1, P)) == pytest.approx(0.2308, abs=1e-4)
    assert float(MissedLooks().after(c2, P)) == c2
    with pytest.raises(ValueError, match="factor"):
        MissedLooks(1.5, 0.5, 1.0)


def test_a_beam_leaves_a_track_where_it_found_nothing():
    # A fixed platform with one 0.1 rad beam (pd 0.8); track 1 3 km east, 100 m sigma
    # (predicted coverage 0.858), track 2 3 km north, 80 m (0.937). The beam serves track 1
    # (det_pos, sum) after one look at it found nothing (M = 0.2, coverage 0.547); after two
    # (M = 0.04, coverage 0.194) track 2 gains more and gets the beam; a hit on track 1 (any
    # sensor's) resets it.
    beam = {"id": "s1", "kind": "range_bearing", "sigma_r": 10.0, "sigma_b": 0.002}
    beam.update(pd=0.8, beam_width=0.1)
    sc = scenario(
        [platform("p1", [0.0, 10.0, 0.0, 0.0], [beam])],
        {"cost": "mre", "criterion": "det_pos", "targets": {"aggregate": "weighted_sum"}},
    )
    t1 = track(1, [3000, 0, 0, 0], np.diag([100.0**2, 4, 100.0**2, 4]))
    t2 = track(2, [0, 0, 3000, 0], np.diag([80.0**2, 4, 80.0**2, 4]))
    planner = build_across_targets(sc, np.random.default_rng(0))
    served, factors = [], []
    for k, (hits, misses) in enumerate([(5, 0), (5, 1), (5, 2), (6, 2)]):
        tracks = (dataclasses.replace(t1, hits=hits, misses=misses), t2)
        d = planner.plan(k, TrackSet(k, 5.0 * k, "ekf", tracks=tracks), snapshots(sc))
        served.append(d.extra["assignment"]["s1"])
        factors.append(planner.miss_factor.get(1, (1.0, 0))[0])
    assert served == [1, 1, 2, 1]
    assert factors == pytest.approx([1.0, 0.2, 0.04, 1.0])
    # The decision's cost of track 1 is eq. 23 with the detection factor q c(M).
    dyn = target_dynamics(sc)
    p = TargetPrediction.from_posterior(t1.mean, t1.cov, dyn.F, dyn.Q)
    pv = np.array([50.0, 10.0, 0.0, 0.0])  # the platform at k+1 (dt 5 s)
    q = 0.8  # one target, no clutter: known association, so pd without a gate (as tracked)
    c = coverage_after_misses(beam_coverage(0.1, p.x, p.P, pv), 0.2)
    assert float(c) == pytest.approx(0.547, abs=1e-3)
    sensor = RangeBearingSensor(10.0, 0.002, pd=0.8)
    P = expected_update(p.P, p.x, [sensor], pv[None], detection=[q * float(c)])
    want = get_criterion("det_pos").of_covariance(p.F @ P @ p.F.T + p.Q, p.x)
    tracks = (dataclasses.replace(t1, hits=5, misses=1), t2)
    again = build_across_targets(sc, np.random.default_rng(0))
    again.plan(
        0, TrackSet(0, 0.0, "ekf", tracks=(dataclasses.replace(t1, hits=5), t2)), snapshots(sc)
    )
    d = again.plan(1, TrackSet(1, 5.0, "ekf", tracks=tracks), snapshots(sc))
    assert d.extra["track_costs"][1] == pytest.approx(float(want), rel=1e-9)


def test_random_assignment_is_seeded_balanced_and_uniform():
    beam = {"kind": "bearing", "sigma": 0.01, "beam_width": 0.2, "r_min": 10.0}
    platforms = [
        platform(f"p{i}", [-5000.0 * i - 100, 10.0, -4000.0, 0.0], [{**beam, "id": f"s{i}"}])
        for i in range(3)
    ]
    sc = scenario(platforms, {"targets": {"assignment": "random"}})
    tracks = [
        track(i, [1000.0 * i, 0, 500.0 * i, 0], np.diag([100, 1, 100, 1.0])) for i in range(5)
    ]

    def run(seed):
        planner = build_across_targets(sc, np.random.default_rng(seed))
        ts = TrackSet(0, 0.0, "ekf", tracks=tuple(tracks))
        out = [
            tuple(planner.plan(k, ts, snapshots(sc)).extra["assignment"].values()) for k in range(6)
        ]
        assert all(len(set(a)) == 3 for a in out)  # three beams, three different tracks
        return out

    assert run(1) == run(1)
    assert run(1) != run(2)
    # Uniform: each of the 6 ordered pairs of 2 beams over 3 tracks 1/6 of 6000 draws (4 sigma).
    rng = np.random.default_rng(3)
    counts = {}
    for _ in range(6000):
        key = tuple(random_assignment(2, 3, rng).tolist())
        counts[key] = counts.get(key, 0) + 1
    assert len(counts) == 6
    assert all(abs(c - 1000) < 4 * math.sqrt(6000 * (1 / 6) * (5 / 6)) for c in counts.values())


# --- one track: the single-target planners ------------------------------------------------------


def test_one_track_pcrlb_equals_plan():
    # Gate 10 sigma and no clutter: q = pd (1 - 1e-20), so the clutter-wrapped sensor is the
    # plain one and the planner must be plan() (same samples, same noise draws).
    sensor = {"id": "s1", "kind": "bearing", "sigma": 0.02, "pd": 0.8}
    platforms = [platform("p1", [0.0, 50.0, 0.0, 0.0], [sensor], controllable=True)]
    mean, cov = np.array([3000.0, 0, 2000, 0]), np.diag([4e4, 4, 4e4, 4])
    X = np.random.default_rng(5).multivariate_normal(mean, cov, 300)
    for R, search in ((1, "quadrant"), (2, "quadrant"), (3, "evolution")):
        sc = scenario(platforms, {"search": search, "horizon": R}, gate=10.0)
        d = decide(sc, [track(1, mean, cov, samples=X)])
        dyn = target_dynamics(sc)
        limits = platform_limits(sc.platforms[0].limits, sc.dt)
        pp = PlannerPlatform("p1", snapshots(sc)[0].pv, (BearingSensor(0.02, pd=0.8),), limits)
        settings = plan_settings(sc.planner)
        belief = TargetBelief(covariance_bound(cov), X)
        rng = np.random.default_rng(0)
        want = plan([pp], belief, settings, F=dyn.F, Q=dyn.Q, dt=sc.dt, rng=rng)
        m = want.manoeuvres[0]
        got = d.commands[0]
        assert (got.heading_change, got.speed_change) == pytest.approx(
            (m.heading_change, m.speed_change), abs=1e-9
        )
        aggregate, objective = d.report.predicted_costs[:2]
        assert objective == pytest.approx(want.report.objective, rel=1e-12)
        assert aggregate == pytest.approx(want.report.predicted["b_k"], rel=1e-12)


def test_one_track_mre_equals_multi_step_positioning():
    # A range-bearing sensor in light clutter: the planner's eq. 23 uses q (0.786) where the
    # single-target positioning uses pd; with pd = q they agree, for one leg and two.
    sensor = {
        "id": "s1",
        "kind": "range_bearing",
        "sigma_r": 20.0,
        "sigma_b": 0.02,
        "pd": 0.8,
        "clutter_density": 1e-4,
        "r_max": 20000.0,
    }
    platforms = [platform("p1", [0.0, 50.0, 0.0, 0.0], [sensor], controllable=True)]
    mean, cov = np.array([3000.0, 0, 2000, 0]), np.diag([4e4, 4, 4e4, 4])
    q = information_reduction_factor(0.8, 1e-4 * 20.0 * 0.02, 3.5, 2)
    assert q == pytest.approx(0.786, abs=1e-3)
    for R in (1, 2):
        planner = {"cost": "mre", "criterion": "det_pos", "search": "sector", "horizon": R}
        sc = scenario(platforms, planner)
        d = decide(sc, [track(1, mean, cov)])
        dyn, s = target_dynamics(sc), snapshots(sc)[0]
        limits = platform_limits(sc.platforms[0].limits, sc.dt)
        single = RangeBearingSensor(20.0, 0.02, pd=q, r_max=20000.0)
        pp = PlannerPlatform("p1", s.pv, (single,), limits, heading=s.heading, speed=s.speed)
        prediction = TargetPrediction.from_posterior(mean, cov, dyn.F, dyn.Q)
        search = SearchSettings("sector", sector_levels=3)
        want = plan_positions(pp, prediction, sc.dt, search=search, horizon=R)
        assert d.commands[0].heading_change == pytest.approx(want.manoeuvre[0], abs=1e-12)
        assert d.commands[0].commanded_speed == pytest.approx(want.manoeuvre[1], abs=1e-12)
        assert d.report.predicted_costs[1] == pytest.approx(want.cost, rel=1e-12)
        assert d.report.horizon == R and d.report.evaluations == want.evaluations


# --- clutter, beams, sweeps ---------------------------------------------------------------------


def _expected_bk(track_cov, samples_next, pv_next, sigma, q, F, Q, criterion="b_k"):
    """b_k of (Q + F J^-1 F^T)^-1 + q E[H^T R^-1 H] (Hernandez eq. 3 and 8, IRF for pd)."""
    J = predicted_information(covariance_bound(track_cov), F, Q)
    if q:
        J = J + q * BearingSensor(sigma, pd=1.0).fisher_information(samples_next, pv_next)
    return float(get_criterion(criterion).of_information(J))


def test_clutter_scales_the_bearing_information_by_the_irf():
    # Bearing sensor sigma 0.01 rad, pd 0.9, 4 false alarms per rad, gate 3.5 sigma: whitened
    # density 0.04 and q = 0.736 (0.894 without clutter: pd F_chi2,3(3.5^2)).
    q = information_reduction_factor(0.9, 4.0 * 0.01, 3.5, 1)
    assert q == pytest.approx(0.736, abs=1e-3)
    assert information_reduction_factor(0.9, 0.0, 3.5, 1) == pytest.approx(0.894, abs=1e-3)
    sensor = {"id": "s1", "kind": "bearing", "sigma": 0.01, "pd": 0.9, "clutter_density": 4.0}
    mean, cov = np.array([3000.0, 3, 2000, -2]), np.diag([900.0, 4, 400, 4])
    X = np.random.default_rng(2).multivariate_normal(mean, cov, 200)
    pv1 = np.array([-2000.0 + 100.0, 20.0, 500.0 + 25.0, 5.0])  # coasting one 5 s leg
    got = {}
    for criterion in ("b_k", "det_pos"):
        planner = {"criterion": criterion}
        sc = scenario([platform("p1", [-2000.0, 20.0, 500.0, 5.0], [sensor])], planner)
        d = decide(sc, [track(4, mean, cov, samples=X)], seed=9)
        dyn = target_dynamics(sc)
        X1 = propagate_samples(X, dyn.F, dyn.Q, 1, np.random.default_rng(9))[0]
        got[criterion] = d.extra["track_costs"][4]
        want = _expected_bk(cov, X1, pv1, 0.01, q, dyn.F, dyn.Q, criterion)
        assert got[criterion] == pytest.approx(want, rel=1e-12)
        plain = _expected_bk(cov, X1, pv1, 0.01, 0.9, dyn.F, dyn.Q, criterion)
        assert got[criterion] > plain  # clutter costs accuracy
    # b_k 31.31 m (31.25 m clutter-free: the bearing informs the cross-range axis only).
    assert got["b_k"] == pytest.approx(31.31, abs=0.01)


def test_the_innovation_gate_q_is_todays_at_S_equal_R_and_falls_as_the_gate_widens():
    # Bearing sensor sigma 0.002 rad, pd 0.9, 5 false alarms per rad: today's q is that of the
    # density whitened by R (5 * 0.002 = 0.01); the innovation gate's that of 5 sqrt(S).
    base = BearingSensor(0.002, pd=0.9)
    x, pv = np.array([3000.0, 0, 2000, 0]), np.array([1000.0, 0, 2000, 0])
    today = ClutteredSensor(base, 5.0, 3.5)
    gated = dataclasses.replace(today, clutter_gate="innovation")
    assert today.information_factor == information_reduction_factor(0.9, 0.01, 3.5, 1)
    P0 = np.zeros((4, 4))
    assert gated.planned_information_factor(x, pv, P0) == pytest.approx(
        today.information_factor, abs=IRF_TABLE_TOLERANCE
    )
    Ps = np.stack([np.diag([v, 1, v, 1]) for v in (0.0, 25.0, 100.0, 400.0, 2500.0)])
    q = gated.planned_information_factor(x, pv, Ps)  # batched over P: (5,)
    for P in Ps:  # the measurement gate: one q, whatever P
        assert today.planned_information_factor(x, pv, P) == today.information_factor
    S = Ps[:, 2, 2] / 2000.0**2 + 0.002**2  # the bearing's innovation variance, x 2 km ahead
    want = [information_reduction_factor(0.9, 5.0 * math.sqrt(v), 3.5, 1) for v in S]
    assert q == pytest.approx(want, abs=IRF_TABLE_TOLERANCE)
    assert all(b < a for a, b in itertools.pairwise(q))
    assert (q[0], q[-1]) == pytest.approx((0.845, 0.539), abs=1e-3)
    with pytest.raises(ValueError, match="clutter_gate must be one of"):
        ClutteredSensor(base, 5.0, 3.5, clutter_gate="gate")
    sensor = {"id": "s1", "kind": "bearing", "sigma": 0.002, "pd": 0.9, "clutter_density": 5.0}
    with pytest.raises(ValueError, match="clutter_gate"):
        scenario([platform("p1", pv, [sensor])], {"targets": {"clutter_gate": "gate"}})
    with pytest.raises(ValueError, match="clutter_gate: 'innovation' sets the information"):
        scenario(
            [platform("p1", pv, [sensor])],
            {"cost": "pcrlb", "targets": {"clutter_gate": "innovation"}},
        )


def test_closing_in_on_a_cluttered_bearing_sensor_costs_with_the_innovation_gate():
    # A track 50 m wide seen in angle from 0.5-4 km: the nearer the sensor, the wider the
    # gate in angle and the more of the sensor's 5 false alarms per rad it holds. With one q
    # (measurement) the nearest position scores best; with the gate's it scores worst.
    mean, cov = np.array([3000.0, 0, 2000, 0]), np.diag([2500.0, 4, 2500, 4])
    sensor = {"id": "s1", "kind": "bearing", "sigma": 0.002, "pd": 0.9, "clutter_density": 5.0}
    ranges = (500.0, 1000.0, 2000.0, 4000.0)
    costs = {}
    for gate in ("measurement", "innovation"):
        planner = {"cost": "mre", "criterion": "trace", "targets": {"clutter_gate": gate}}
        costs[gate] = []
        for r in ranges:
            pv = np.array([3000.0 - r, 0.0, 2000.0, 0.0])
            sc = scenario([platform("p1", pv, [sensor])], planner)
            costs[gate].append(decide(sc, [track(1, mean, cov)]).extra["track_costs"][1])
            if gate == "innovation":  # eq. 23 with q of S = H P H^T + R, by hand
                dyn = target_dynamics(sc)
                P = dyn.F @ cov @ dyn.F.T + dyn.Q
                x = dyn.F @ mean
                model = BearingSensor(0.002, pd=0.9)
                H = model.jacobian(x, pv)
                S = float((H @ P @ H.T)[0, 0]) + 0.002**2
                q = information_reduction_factor(0.9, 5.0 * math.sqrt(S), 3.5, 1)
                P1 = dyn.F @ mre_update(P, H, model.R, q) @ dyn.F.T + dyn.Q
                assert costs[gate][-1] == pytest.approx(np.trace(P1), rel=1e-5)
    assert all(b > a for a, b in itertools.pairwise(costs["measurement"]))
    assert all(b < a for a, b in itertools.pairwise(costs["innovation"]))
    assert costs["measurement"][0] == pytest.approx(3444.2, abs=0.1)
    assert costs["innovation"][0] == pytest.approx(5196.4, abs=0.1)


def test_a_beam_informs_only_its_track_and_points_at_it():
    beam = {"id": "s1", "kind": "bearing", "sigma": 0.01, "beam_width": 0.2, "clutter_density": 2}
    sc = scenario(
        [platform("p1", [0.0, 20.0, 0.0, 0.0], [beam])], {"targets": {"assignment": "nearest"}}
    )
    cov = np.diag([400.0, 4, 400, 4])
    rng = np.random.default_rng(4)
    Xn = rng.multivariate_normal([2000, 0, 1000, 0], cov, 100)
    Xf = rng.multivariate_normal([-6000, 0, 3000, 0], cov, 100)
    near = track(1, [2000, 0, 1000, 0], cov, samples=Xn)
    far = track(2, [-6000, 0, 3000, 0], cov, samples=Xf)
    d = decide(sc, [far, near], seed=1)
    dyn = target_dynamics(sc)
    noise = np.random.default_rng(1)
    X1f = propagate_samples(Xf, dyn.F, dyn.Q, 1, noise)[0]  # track order: far, then near
    X1n = propagate_samples(Xn, dyn.F, dyn.Q, 1, noise)[0]
    pv1 = np.array([100.0, 20.0, 0.0, 0.0])
    q = information_reduction_factor(1.0, 2 * 0.01, 3.5, 1)
    costs = d.extra["track_costs"]
    assert costs[2] == _expected_bk(cov, X1f, pv1, 0.01, 0.0, dyn.F, dyn.Q)  # nothing
    assert costs[1] == pytest.approx(_expected_bk(cov, X1n, pv1, 0.01, q, dyn.F, dyn.Q), rel=1e-12)
    assert (costs[1], costs[2]) == pytest.approx((21.11, 22.37), abs=0.01)  # b_k [m]
    assert d.extra["assignment"] == {"s1": 1}
    (b,) = d.beams
    x1 = dyn.F @ near.mean
    assert (b.track_id, b.epoch) == (1, 0)
    assert b.bearing == pytest.approx(math.atan2(x1[2] - pv1[2], x1[0] - pv1[0]), abs=1e-12)


def test_beam_candidates_hold_every_group_that_fits_in_the_beam():
    # 0 and 0.1 fit in a 0.35 rad beam (centre 0.05), 0.5 is 0.4 from 0.1: alone.
    got = beam_candidates([0.5, 0.0, 0.1], 0.35)
    assert got == pytest.approx([0.0, 0.05, 0.1, 0.5], abs=1e-12)
    # Across +-pi: -3.1 is 0.1832 counter-clockwise of 3.0, the pair's centre 3.0916.
    got = beam_candidates([3.0, -3.1], 0.35)
    assert got == pytest.approx([-3.1, 3.0, 3.0 + 0.5 * (2 * math.pi - 6.1)], abs=1e-12)


def _two_near_one_far():
    """A bearing sensor at the origin; tracks 3 km off at bearings 0 and 0.1 and one at 1.2,
    300 m across (0.1 rad: a 0.35 rad beam holds the target with probability 0.92)."""
    F = np.array([[1.0, 5.0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 5.0], [0, 0, 0, 1.0]])
    Q = np.diag([0.2, 0.05, 0.2, 0.05])
    P = np.diag([300.0**2, 4.0, 300.0**2, 4.0])
    preds = [
        TargetPrediction(np.array([3000 * math.cos(b), 0, 3000 * math.sin(b), 0]), P, F, Q)
        for b in (0.0, 0.1, 1.2)
    ]
    return preds, [ClutteredSensor(BearingSensor(0.01, pd=0.9), beam_width=0.35)], np.zeros((1, 4))


def test_a_footprint_beam_is_centred_between_two_tracks_it_holds_both():
    preds, sensors, pvs = _two_near_one_far()
    d = np.full((1, 3), 0.9)
    bearings, holds = footprint_pointing(
        preds, sensors, pvs, d, [NO_MISSES] * 3, "trace", np.ones(3)
    )
    assert holds.tolist() == [[True, True, False]]
    assert bearings[0] == pytest.approx(0.05, abs=1e-12)
    # Its gain is both tracks' updates, each with the chance the beam holds its target.
    crit = get_criterion("trace")

    def cost(p, factor=None):
        P = p.P if factor is None else expected_update(p.P, p.x, sensors, pvs, detection=[factor])
        return float(crit.of_covariance(p.F @ P @ p.F.T + p.Q, p.x))

    c = [float(beam_coverage(0.35, p.x, p.P, pvs[0])) for p in preds]
    off = [float(sector_coverage(0.35, 0.05, p.x, p.P, pvs[0])) for p in preds[:2]]
    assert c[0] == pytest.approx(math.erf(0.175 / (0.1 * math.sqrt(2))), abs=1e-3)
    # 0.05 off centre: (erf(0.125 / (sqrt 2 0.1)) + erf(0.225 / (sqrt 2 0.1))) / 2 = 0.882
    assert off == pytest.approx([0.882, 0.882], abs=1e-3) and off[0] < c[0]
    footprint = sum(cost(p) - cost(p, 0.9 * o) for p, o in zip(preds[:2], off, strict=True))
    alone = max(cost(p) - cost(p, 0.9 * ci) for p, ci in zip(preds, c, strict=True))
    assert footprint > 1.9 * alone  # what a beam credited with one track leaves out


def test_footprints_that_hold_one_track_each_are_the_track_assignment():
    rng = np.random.default_rng(11)
    for _ in range(6):  # tracks farther apart in bearing than the beams are wide
        preds, sensors, pvs, d = _random_geometry(rng, 1, 3)
        theta = [math.atan2(p.x[2] - pvs[0, 2], p.x[0] - pvs[0, 0]) for p in preds]
        gaps = np.abs(wrap_angle(np.subtract.outer(theta, theta)))[np.triu_indices(3, 1)]
        width = 0.9 * float(gaps.min())
        beam = [ClutteredSensor(sensors[0], beam_width=width)]
        cover = np.array([[float(beam_coverage(width, p.x, p.P, pvs[0])) for p in preds]])
        bearings, holds = footprint_pointing(
            preds, beam, pvs, d, [NO_MISSES] * 3, "trace", np.ones(3)
        )
        t = assign_beams(preds, beam, pvs, d * cover, "trace", np.ones(3), "weighted_sum")[0]
        assert holds.sum() == 1 and holds[0, t]
        assert bearings[0] == pytest.approx(theta[t], abs=1e-12)


def test_pointing_footprint_centres_the_planners_beam_between_its_tracks():
    beam = {"id": "s1", "kind": "bearing", "sigma": 0.01, "beam_width": 0.35}
    planner = {
        "criterion": "trace",
        "targets": {"aggregate": "weighted_sum", "pointing": "footprint"},
    }
    sc = scenario([platform("p1", [0.0, 0.0, 0.0, 0.0], [beam])], planner)
    cov = np.diag([300.0**2, 4.0, 300.0**2, 4.0])
    tracks = [
        track(i + 1, [3000 * math.cos(b), 0, 3000 * math.sin(b), 0], cov)
        for i, b in enumerate((0.0, 0.1, 1.2))
    ]
    d = decide(sc, tracks)
    (b,) = d.beams
    assert b.bearing == pytest.approx(0.05, abs=1e-12) and b.track_id in (1, 2)
    with pytest.raises(ValueError, match="pointing: 'footprint' centres beams"):
        scenario(
            [platform("p1", [0.0, 0.0, 0.0, 0.0], [beam])],
            {"targets": {"objective": "gospa", "pointing": "footprint"}},
        )
    with pytest.raises(ValueError, match="use aggregate 'weighted_sum'"):
        scenario(
            [platform("p1", [0.0, 0.0, 0.0, 0.0], [beam])],
            {"targets": {"aggregate": "worst", "pointing": "footprint"}},
        )


def test_no_confirmed_track_sweeps_the_beams_and_holds_course():
    beam = {"id": "s1", "kind": "range_bearing", "sigma_r": 10.0, "sigma_b": 0.01}
    beam.update(beam_width=0.5, r_max=20000.0, clutter_density=1e-5)
    sc = scenario([platform("p1", [0.0, 30.0, 0.0, 30.0], [beam], controllable=True)])
    planner = build_across_targets(sc, np.random.default_rng(0))
    tentative = TrackSet(
        0, 0.0, "ekf", tracks=(track(7, [500, 0, 500, 0], np.eye(4), "tentative"),)
    )
    bearings = []
    for k in range(3):
        d = planner.plan(k, tentative, snapshots(sc))
        assert [(c.heading_change, c.speed_change) for c in d.commands] == [(0.0, 0.0)]
        assert d.report.search == "sweep" and d.extra["assignment"] == {"s1": -1}
        bearings.append(d.beams[0].bearing)
    assert bearings == pytest.approx([math.pi / 4, math.pi / 4 + 0.5, math.pi / 4 + 1.0])
    confirmed = TrackSet(3, 0.0, "ekf", tracks=(track(7, [500, 0, 500, 0], np.eye(4)),))
    d = planner.plan(3, confirmed, snapshots(sc))
    assert d.beams[0].track_id == 7 and d.report.search == "quadrant"
    pointed = d.beams[0].bearing
    d = planner.plan(4, TrackSet(4, 0.0, "ekf"), snapshots(sc))  # the track is gone
    assert d.beams[0].track_id == -1
    assert d.beams[0].bearing == pytest.approx(pointed + 0.5)  # the sweep goes on from it


def test_planner_off_holds_course_and_still_assigns_beams():
    beam = {"kind": "range_bearing", "sigma_r": 10.0, "sigma_b": 0.01, "beam_width": 0.05}
    platforms = [
        platform("p1", [0.0, 30.0, 0.0, 0.0], [{**beam, "id": "s1"}], controllable=True),
        platform("p2", [8000.0, 0.0, 0.0, 30.0], [{**beam, "id": "s2", "sigma_r": 50.0}]),
    ]
    sc = scenario(platforms, {"enabled": False, "cost": "mre", "criterion": "det_pos"})
    tracks = [
        track(1, [1000, 10, 3000, 0], np.diag([900.0, 4, 900, 4])),
        track(2, [7000, 0, 2000, -10], np.diag([4e4, 9, 4e4, 9])),
        track(3, [4000, 0, -2000, 0], np.diag([400.0, 4, 400, 4])),
    ]
    d = decide(sc, tracks)
    assert [(c.platform_id, c.heading_change, c.speed_change) for c in d.commands] == [
        ("p1", 0.0, 0.0)
    ]
    dyn = target_dynamics(sc)
    preds = [TargetPrediction.from_posterior(t.mean, t.cov, dyn.F, dyn.Q) for t in tracks]
    pvs = np.array([[150.0, 30.0, 0.0, 0.0], [8000.0, 0.0, 150.0, 30.0]])  # coasting
    sensors = [RangeBearingSensor(10.0, 0.01), RangeBearingSensor(50.0, 0.01)]
    q = information_reduction_factor(1.0, 0.0, 3.5, 2)
    factors = np.array([[q * beam_coverage(0.05, p.x, p.P, pv) for p in preds] for pv in pvs])
    assert factors.min() < 0.5 * q  # track 2 does not fit in p2's beam
    want = assign_beams(preds, sensors, pvs, factors, "det_pos", np.ones(3), "worst")
    # Track 2 (200 m) is worst; p2's beam would hold it with probability 0.20 only, p1's with
    # 0.62: p1 takes it. Beams assumed on target would send p2's.
    assert want.tolist() == [1, 0]
    on_target = np.full((2, 3), q)
    assert assign_beams(preds, sensors, pvs, on_target, "det_pos", np.ones(3), "worst")[1] == 1
    assert d.extra["assignment"] == {"s1": int(want[0]) + 1, "s2": int(want[1]) + 1}
    assert d.report.search == "hold"
