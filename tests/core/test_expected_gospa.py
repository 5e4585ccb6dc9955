"""The planner's expected-GOSPA objective (issue 25 item 3, ``planner.targets.objective: gospa``).

- E[min(d, c)^p] in closed form against Monte Carlo of an isotropic Gaussian error (p = 1, 2,
  3) and against its limits (m << c^2: E[d^p]; m >> c^2: c^p);
- one track, a beam covers it or not: missed = (1 - q) c^p / alpha by hand, existence r adds
  (1 - r) c^p / alpha of false track, localisation weighted by r h;
- the beam assignment on expected GOSPA serves the track at risk of being lost (wide, beyond
  the cut-off without a look), where the MRE assignment of b_k serves the sharper one;
- the tracker's termination rule: an epoch without a detection takes r to r (1 - q) / (1 - r
  q); where that ends the track, its false-track term goes (by hand), so the beam looks at a
  track whose target may have died when the look ends it;
- the rollout scores R legs (straight on after the first) and hold course is kept on a tie;
- the setting is checked (name, GOSPA's fields) and refused for one known target.
"""

import math

import numpy as np
import pytest

from activetrack.bounds.mre import mre_update
from activetrack.closed_loop.components import build_across_targets
from activetrack.data import PlatformSnapshot, TrackEstimate, TrackSet, heading_speed
from activetrack.models.sensors import BearingSensor
from activetrack.planning.assignment import MissedLooks, assign_beams_gospa, gospa_pair_costs
from activetrack.planning.expected_gospa import (
    GospaWeights,
    beyond_cutoff,
    expected_localisation,
    hit_probability,
    hold_update,
    managed_split,
    miss_existence,
    position_spread,
    track_split,
)
from activetrack.planning.gospa_rollout import GospaRollout, Look, straight_on
from activetrack.planning.selection import TargetPrediction
from activetrack.scenarios import parse_scenario

W = GospaWeights(500.0, 2.0, 2.0)  # the multi-target scenarios' evaluation: c^p / alpha = 125000


@pytest.mark.parametrize("p", [1.0, 2.0, 3.0])
@pytest.mark.parametrize("m", [2.0e4, 2.5e5, 1.0e6])
def test_expected_localisation_matches_monte_carlo(p, m):
    rng = np.random.default_rng(3)
    e = rng.normal(0.0, math.sqrt(m / 2.0), size=(400_000, 2))  # isotropic, E[d^2] = m
    d = np.hypot(e[:, 0], e[:, 1])
    want = np.mean(np.minimum(d, 500.0) ** p)
    assert expected_localisation(m, 500.0, p) == pytest.approx(want, rel=5e-3)
    assert beyond_cutoff(m, 500.0) == pytest.approx(np.mean(d > 500.0), abs=2e-3)


def test_expected_localisation_limits():
    # m << c^2: E[d^2] = m and E[d] = sqrt(pi m) / 2 (Rayleigh); m >> c^2: saturates at c^p.
    assert expected_localisation(100.0, 500.0, 2.0) == pytest.approx(100.0, rel=1e-12)
    assert expected_localisation(100.0, 500.0, 1.0) == pytest.approx(
        math.sqrt(math.pi * 100.0) / 2.0, rel=1e-9
    )
    assert expected_localisation(1e12, 500.0, 2.0) == pytest.approx(250000.0, rel=1e-6)
    # p = 2 in closed form: m (1 - exp(-c^2 / m)); m = 2.5e5: 2.5e5 (1 - e^-1) = 158030.1
    assert expected_localisation(2.5e5, 500.0, 2.0) == pytest.approx(158030.14, abs=0.01)
    assert expected_localisation(0.0, 500.0, 2.0) == 0.0


def test_one_track_beam_covers_it_or_not():
    # A track far beyond the cut-off (P(d > c) = 1): held only if detected. Beam on it with
    # Pd 0.9 and coverage 0.8: q = 0.72, expected missed = (1 - q) c^p / alpha = 35000, the same
    # again as false track; no beam: q = 0, one missed and one false (c^p = 250000).
    m_pred = math.inf
    for q, missed in ((0.72, 35000.0), (0.0, 125000.0)):
        h = hold_update(1.0, q, m_pred, 500.0)
        assert h == pytest.approx(q, abs=1e-12)
        loc, miss, false = track_split(1.0, h, 100.0, W)
        assert miss == pytest.approx(missed, rel=1e-12)
        assert false == pytest.approx(missed, rel=1e-12)
        assert loc == pytest.approx(q * 100.0, rel=1e-9)
    # Existence 0.6, held (h = 1), spread 400 m^2: loc 0.6 x 400 = 240, missed 0, false 0.4 x
    # 125000 = 50000.
    assert track_split(0.6, 1.0, 400.0, W) == pytest.approx([240.0, 0.0, 50000.0], rel=1e-9)
    # A track well inside the cut-off is not lost by a missed look: P(d > c) = exp(-25).
    assert hold_update(1.0, 0.0, 1e4, 500.0) == pytest.approx(1.0 - math.exp(-25.0), rel=1e-15)
    assert hit_probability([0.5, 0.2]) == pytest.approx(0.6)
    assert hit_probability(np.zeros((3, 0))).tolist() == [0.0, 0.0, 0.0]


def test_gospa_weights_are_checked():
    with pytest.raises(ValueError, match="c must be finite and > 0"):
        GospaWeights(0.0, 2.0, 2.0)
    with pytest.raises(ValueError, match="alpha"):
        GospaWeights(500.0, 2.0, 3.0)
    with pytest.raises(ValueError, match="p"):
        GospaWeights(500.0, 0.5, 2.0)
    assert GospaWeights(100.0, 1.0, 1.0).cardinality == 100.0


def _prediction(x, var):
    F = np.eye(4)
    F[0, 1] = F[2, 3] = 5.0
    return TargetPrediction(np.asarray(x, float), np.diag(var).astype(float), F, 0.01 * np.eye(4))


def test_the_pair_costs_by_hand():
    # One bearing sensor at the origin, one track at (3000, 0) with spread m = 2 x 4e4; the
    # beam's update (detection factor 0.5) and chance of a hit 0.45, no other sensor.
    sensor = BearingSensor(sigma=0.01, pd=0.9, r_min=100.0)
    p = _prediction([3000.0, 0.0, 0.0, 0.0], [4e4, 1.0, 4e4, 1.0])
    pv = np.array([[0.0, 0.0, 0.0, 0.0]])
    m_pred = 8e4
    C, c0 = gospa_pair_costs([p], [sensor], pv, [[0.5]], [[0.45]], ([0.0], [m_pred], [1.0]), W)
    lost = math.exp(-250000.0 / m_pred)
    want0 = (1 - lost) * expected_localisation(m_pred, 500.0, 2.0) + lost * 250000.0
    assert c0[0] == pytest.approx(want0, rel=1e-12)
    H = sensor.jacobian(p.x, pv[0])
    m_upd = position_spread(mre_update(p.P, H, sensor.R, 0.5))
    h = 1.0 - 0.55 * lost
    want = h * expected_localisation(m_upd, 500.0, 2.0) + (1 - h) * 250000.0
    assert C[0, 0] == pytest.approx(want, rel=1e-12)
    assert C[0, 0] < c0[0]


def test_the_beam_goes_where_a_track_is_at_risk():
    # Two tracks, one beam. Track 0 sharp (20 m), track 1 wide (400 m, near the cut-off): the
    # expected-GOSPA assignment serves the wide one (a look keeps it from being lost); its
    # gain dwarfs the sharp track's.
    sensor = BearingSensor(sigma=0.01, pd=0.9, r_min=100.0)
    preds = [
        _prediction([3000.0, 0.0, 500.0, 0.0], [400.0, 1.0, 400.0, 1.0]),
        _prediction([3000.0, 0.0, -500.0, 0.0], [1.6e5, 1.0, 1.6e5, 1.0]),
    ]
    pv = np.zeros((1, 4))
    spreads = [position_spread(p.P) for p in preds]
    C, c0 = gospa_pair_costs(
        preds, [sensor], pv, [[0.9, 0.9]], [[0.9, 0.9]], ([0.0, 0.0], spreads, [1.0, 1.0]), W
    )
    gains = c0 - C[0]
    assert gains[1] > 100.0 * gains[0] > 0.0
    picks = assign_beams_gospa(
        preds, [sensor], pv, [[0.9, 0.9]], [[0.9, 0.9]], ([0.0, 0.0], spreads, [1.0, 1.0]), W,
        np.ones(2),
    )  # fmt: skip
    assert picks.tolist() == [1]


def test_a_miss_lowers_existence_and_may_end_the_track():
    assert miss_existence(0.5, 0.8) == pytest.approx(0.1 / 0.6, rel=1e-12)
    assert miss_existence(1.0, 1.0) == 0.0 and miss_existence(1.0, 0.5) == 1.0
    # r = 0.46 (a confirmed track after one epoch without a detection by both radars), q =
    # 0.98: r' = 0.46 * 0.02 / (1 - 0.4508) = 0.016752, below 0.02: the track ends.
    assert miss_existence(0.46, 0.98) == pytest.approx(0.0092 / 0.5492, rel=1e-12)
    ended = managed_split(0.46, 0.98, 1e4, 100.0, W, 0.02)
    # held r q m (1 - e^-2500), missed r (1 - q) c^2 / 2, no false track
    assert ended == pytest.approx([0.46 * 0.98 * 100.0, 0.46 * 0.02 * 125000.0, 0.0], rel=1e-9)
    # below the threshold it is kept: track_split with the hold after the epoch
    kept = managed_split(0.46, 0.98, 1e4, 100.0, W, 0.01)
    h = hold_update(1.0, 0.98, 1e4, 500.0)
    assert kept == pytest.approx(track_split(0.46, h, 100.0, W), rel=1e-12)
    assert kept[2] == pytest.approx(0.54 * 125000.0, rel=1e-6)


def test_the_beam_ends_a_track_whose_target_may_have_died():
    # Two tracks, one beam, a fixed sensor that detects either with 0.8. Track 0 is held (r =
    # 1, 400 m^2 spread), track 1 has gone an epoch without a detection (r = 0.46). Without the
    # termination rule (threshold 0) no look changes track 1's false-track term (1 - r) c^p /
    # alpha and the beam serves track 0; with the tracker's 0.02 a look without a detection
    # ends track 1 (0.46 x 0.02 / 0.5492 = 0.0168; the fixed sensor alone: 0.146), which saves
    # that term, and the beam goes to it.
    sensor = BearingSensor(sigma=0.01, pd=0.9, r_min=100.0)
    preds = [
        _prediction([3000.0, 0.0, 500.0, 0.0], [200.0, 1.0, 200.0, 1.0]),
        _prediction([3000.0, 0.0, -500.0, 0.0], [200.0, 1.0, 200.0, 1.0]),
    ]
    pv = np.zeros((1, 4))
    base = ([0.8, 0.8], [position_spread(p.P) for p in preds], [1.0, 0.46])
    args = (preds, [sensor], pv, [[0.9, 0.9]], [[0.9, 0.9]], base, W, np.ones(2))
    assert assign_beams_gospa(*args).tolist() == [0]
    assert assign_beams_gospa(*args, terminate=0.02).tolist() == [1]
    C, c0 = gospa_pair_costs(*args[:7], terminate=0.02)
    # the gain: the false track's term less the missed target's r (1 - q) c^p / alpha (the
    # localisation terms differ by tens of m^2)
    assert c0[1] - C[0, 1] == pytest.approx(0.54 * 125000.0 - 0.46 * 0.02 * 125000.0, abs=100.0)


def test_the_rollout_counts_every_leg_and_goes_straight_on():
    # No sensor serves the track (mre kind): legs 1 and 2 cost the predictions' split; the
    # track is held through leg r with prod (1 - P(d > c)) of the predicted spreads.
    F = np.eye(4)
    F[0, 1] = F[2, 3] = 5.0
    Q = np.diag([10.0, 1.0, 10.0, 1.0])
    P1 = np.diag([5e4, 100.0, 5e4, 100.0])
    x = np.array([[[1000.0, 10.0, 0.0, 0.0]], [[1050.0, 10.0, 0.0, 0.0]]])  # (L=2, T=1, 4)
    sensor = BearingSensor(sigma=0.01, pd=0.9, r_min=100.0)
    far = Look(sensor, np.array([False]), np.zeros((2, 4)))
    stage = GospaRollout(
        "mre", F, Q, x, [], (far,), (), (MissedLooks(),), np.array([0.8]), W, 5.0
    )  # fmt: skip
    got = stage.advance(P1[None], 0, np.zeros((3, 4)))
    assert got.shape == (3, 1, 3)
    P2 = F @ P1 @ F.T + Q
    h1 = 1.0 - beyond_cutoff(1e5, 500.0)
    h2 = h1 * (1.0 - beyond_cutoff(position_spread(P2), 500.0))
    want = track_split(0.8, h1, 1e5, W) + track_split(0.8, h2, position_spread(P2), W)
    assert got[0, 0] == pytest.approx(want, rel=1e-12)
    path = straight_on(np.array([0.0, 10.0, 5.0, -2.0]), 3, 5.0)
    assert path.tolist() == [[0, 10, 5, -2], [50, 10, -5, -2], [100, 10, -15, -2]]


LIMITS = {"dpsi_max": 0.6, "dv_max": 10.0, "v_min": 30.0, "v_max": 120.0}


def _scene(targets_planner, beam=True, clutter=0.0):
    sensor = {"id": "s1", "kind": "bearing", "sigma": 0.01, "pd": 0.9, "r_min": 100.0}
    if beam:
        sensor["beam_width"] = 0.35
    if clutter:
        sensor["clutter_density"] = clutter
    return {
        "name": "gospa_test",
        "dt": 5.0,
        "steps": 10,
        "targets": [
            {
                "id": "t1",
                "motion": {"model": "ncv", "q": 0.01},
                "prior": {"mean": [1000.0, 1.0, 1000.0, 1.0], "var": [100.0, 1.0, 100.0, 1.0]},
            }
        ],
        "platforms": [
            {
                "id": "p1",
                "initial_state": [0.0, 50.0, 0.0, 0.0],
                "controllable": True,
                "limits": LIMITS,
                "sensors": [sensor],
            }
        ],
        "tracker": {"filter": "ekf"},
        "planner": {"horizon": 2, "targets": targets_planner},
    }


def test_hold_course_is_kept_when_no_manoeuvre_scores_better():
    # The only track lies 100 km away, beyond the sensor's r_max (2 km) from anywhere the
    # platform reaches in two legs: every candidate scores the same, and hold course stays.
    data = _scene({"objective": "gospa", "aggregate": "weighted_sum"})
    data["platforms"][0]["sensors"][0]["r_max"] = 2000.0
    sc = parse_scenario(data, "g")
    planner = build_across_targets(sc, np.random.default_rng(0))
    pv = np.array(sc.platforms[0].initial_state)
    snap = [PlatformSnapshot("p1", 0, 0.0, pv, *heading_speed(pv))]
    m = np.array([1e5, 0.0, 0.0, 0.0])
    P = np.diag([100.0, 1.0, 100.0, 1.0])
    tracks = (TrackEstimate(1, "confirmed", m, P, m, P),)
    d = planner.plan(0, TrackSet(0, 0.0, "ekf", tracks=tracks), snap)
    assert (d.commands[0].heading_change, d.commands[0].speed_change) == (0.0, 0.0)
    assert d.report.search == "hold"
    # the objective: two legs of prediction only (no look), all localisation
    assert d.report.predicted_costs[1] > d.report.predicted_costs[0] > 200.0


def test_the_setting_is_checked():
    with pytest.raises(ValueError, match="planner.targets.objective"):
        parse_scenario(_scene({"objective": "ospa"}), "g")
    # one target known to be the only one, no beam: planned on planner.criterion
    with pytest.raises(ValueError, match="planner.targets.objective: 'gospa' plans across"):
        parse_scenario(_scene({"objective": "gospa"}, beam=False), "g")
    assert parse_scenario(_scene({"objective": "gospa"}, beam=False, clutter=1.0), "g")
