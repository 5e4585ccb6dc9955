"""Smoke and equality tests of benchmarks/multitarget.py's own functions (part 1: JPDA against
Stone Soup; part 2: Stone Soup's sensor manager pointing beams) on tiny cases. No timing is
asserted. Skipped without Stone Soup (bench-only)."""

from __future__ import annotations

import importlib.util
import math
import sys
from copy import deepcopy
from dataclasses import replace
from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest

from activetrack.closed_loop.components import target_dynamics
from activetrack.data import PlatformSnapshot, TrackEstimate, TrackSet
from activetrack_experiments import stonesoup_manager as ssm

pytest.importorskip("stonesoup")

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "multitarget.py"
_spec = importlib.util.spec_from_file_location("bench_multitarget", _PATH)
assert _spec is not None and _spec.loader is not None
mt = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = mt  # dataclasses look their module up while the class is built
_spec.loader.exec_module(mt)

SC = mt.JPDAScenario()


def test_targets_set_up_to_meet_at_the_crossing_halfway():
    for n in (3, 4, 5):
        x0 = mt.initial_states(SC, n)
        half = 0.5 * SC.n_steps * SC.T
        at_half = x0[:, [0, 2]] + half * x0[:, [1, 3]]
        np.testing.assert_allclose(at_half, np.broadcast_to(SC.crossing, (n, 2)), atol=1e-9)
        np.testing.assert_allclose(np.hypot(x0[:, 1], x0[:, 3]), SC.speed)
        # Headings pi (i + 1/2) / n: no two targets move in parallel.
        heading = np.arctan2(x0[:, 3], x0[:, 1])
        np.testing.assert_allclose(np.diff(heading), math.pi / n)


def test_scans_hold_detections_and_clutter_at_the_stated_rates():
    """5 runs of 40 scans, 3 targets: the mean scan size is Pd n + lambda V = 2.7 + 18.85 =
    21.55; its sd per scan is about 4.4, so the 200-scan mean is within 1.3 (4 SE)."""
    scans = [z for seed in range(7, 12) for z in mt.simulate(SC, seed, 3).scans]
    sizes = np.array([len(z) for z in scans])
    V = SC.fov_width * (SC.r_max - SC.r_min)
    assert abs(sizes.mean() - (SC.pd * 3 + SC.clutter_density * V)) < 1.3
    Z = np.concatenate(scans)
    assert Z.min(axis=0)[0] >= SC.r_min and Z.max(axis=0)[0] <= SC.r_max
    # Bearings near +-pi on both sides of the cut: the wrap is exercised.
    assert (Z[:, 1] > 3.0).sum() > 100 and (Z[:, 1] < -3.0).sum() > 100
    assert np.all(np.abs(np.abs(Z[:, 1]) - math.pi) <= 0.5 * SC.fov_width + 1e-12)


def test_runs_are_reproducible_from_their_seed():
    a, b = mt.simulate(SC, 11, 4), mt.simulate(SC, 11, 4)
    np.testing.assert_array_equal(a.truth, b.truth)
    np.testing.assert_array_equal(a.prior_means, b.prior_means)
    assert all(np.array_equal(x, y) for x, y in zip(a.scans, b.scans, strict=True))
    c = mt.simulate(SC, 12, 4)
    assert not np.array_equal(a.prior_means, c.prior_means)


def test_mean_gospa_of_exact_and_shifted_estimates():
    sc = replace(SC, n_steps=5)
    run = mt.simulate(sc, 3, 4)
    truth = run.truth[1:]
    assert mt.mean_gospa(sc, run, truth) == 0.0
    shifted = truth + np.array([3.0, 0.0, 4.0, 0.0])  # 5 m off per target
    assert mt.mean_gospa(sc, run, shifted) == pytest.approx(5.0 * math.sqrt(4), rel=1e-12)
    # Beyond the cut-off each target is one miss and one false track: (2 n c^2 / 2)^(1/2).
    far = truth + np.array([2 * sc.cutoff, 0.0, 0.0, 0.0])
    assert mt.mean_gospa(sc, run, far) == pytest.approx(sc.cutoff * math.sqrt(4), rel=1e-12)


def test_ours_matches_stonesoup_jpda_run_by_run():
    """12 scans (crossing not reached), 3 and 4 targets: the two filters' tracks agree to
    0.1 mm and their time-averaged GOSPA to 1e-5 m (measured: 4e-6 m and 5e-7 m; the rest is
    Stone Soup's finite-difference Jacobian)."""
    sc = replace(SC, n_steps=12)
    c = mt.compare_jpda(sc, [2000, 2001], warm_up=False)
    assert c.n_targets == [3, 4]
    assert c.max_state_diff.max() < 1e-4
    np.testing.assert_allclose(c.gospa_ours, c.gospa_theirs, rtol=0, atol=1e-5)
    assert np.all((c.gospa_ours > 1.0) & (c.gospa_ours < sc.cutoff * 2))
    assert c.times_ours.shape == c.times_theirs.shape == (2, 12)
    d, se = c.gospa_diff
    assert abs(d) < 1e-5 and se < 1e-5


def test_stonesoup_jacobian_loses_accuracy_at_negative_coordinates():
    """Why the scenario keeps positions positive (module docstring): Stone Soup's step falls
    to 1e-8 for a negative state entry."""
    from stonesoup.types.array import StateVector
    from stonesoup.types.state import State

    mm = mt._stonesoup_measurement_model(SC, np.zeros(4))

    def range_row_error(x: float, y: float) -> float:
        J = mm.jacobian(State(StateVector([x, 5.0, y, -5.0])))
        r = math.hypot(x, y)
        return float(np.max(np.abs(J[1, [0, 2]] - np.array([x / r, y / r]))))

    assert range_row_error(7000.0, 300.0) < 1e-6
    assert range_row_error(-7000.0, 300.0) > 1e-5


def test_comparison_figures():
    c = mt.JPDAComparison(
        seeds=[1, 2, 3],
        n_targets=[3, 4, 5],
        gospa_ours=np.array([10.0, 12.0, 14.0]),
        gospa_theirs=np.array([11.0, 12.0, 15.0]),
        max_state_diff=np.zeros(3),
        times_ours=np.full((3, 2), 1e-3),
        times_theirs=np.array([[1e-2, 1e-2], [2e-2, 2e-2], [3e-2, 3e-2]]),
    )
    d, se = c.gospa_diff
    assert d == pytest.approx(-2.0 / 3.0)
    assert se == pytest.approx(np.std([-1.0, 0.0, -1.0], ddof=1) / math.sqrt(3))
    assert c.speedup == pytest.approx(20.0)
    lo, hi = c.speedup_spread()
    assert lo == pytest.approx(12.0) and hi == pytest.approx(28.0)


# --- part 2: Stone Soup's sensor manager pointing scenario (b)'s beams -----------------------

SCENARIO_B = mt.load_scenario(mt.SCENARIO_B)
PLATFORMS_B = [
    PlatformSnapshot(p.id, 0, 0.0, np.array(p.initial_state, dtype=float),
                     math.atan2(p.initial_state[3], p.initial_state[1]),
                     math.hypot(p.initial_state[1], p.initial_state[3]))
    for p in SCENARIO_B.platforms
]  # fmt: skip


def _track(track_id: int, mean, pos_var: float, vel_var: float = 1.0) -> TrackEstimate:
    cov = np.diag([pos_var, vel_var, pos_var, vel_var])
    mean = np.asarray(mean, dtype=float)
    return TrackEstimate(track_id, "confirmed", mean, cov, mean, cov)


def _next_xy(platform_id: str) -> np.ndarray:
    """A platform's hold-course position one epoch on."""
    pv = next(s.pv for s in PLATFORMS_B if s.platform_id == platform_id)
    return pv[[0, 2]] + SCENARIO_B.dt * pv[[1, 3]]


def _bearing_from(platform_id: str, mean: np.ndarray) -> float:
    """The bearing from a platform's next position to a track's prediction F x."""
    F = target_dynamics(SCENARIO_B).F
    x = F @ mean
    p = _next_xy(platform_id)
    return math.atan2(x[2] - p[1], x[0] - p[0])


@pytest.mark.parametrize("kind", ["range_bearing", "bearing"])
def test_listed_dwell_actions_offer_and_reach_exactly_the_listed_bearings(kind):
    """The generator yields one action per listed bearing, each reached (the shorter way,
    across the -pi/pi cut too) within the epoch: rpm = one turn per epoch."""
    from stonesoup.types.array import StateVector

    radar = ssm.listed_radars()[0 if kind == "range_bearing" else 1]
    noise = np.diag([1e-4, 100.0]) if kind == "range_bearing" else np.array([[1e-4]])
    listed = (3.0, -3.0, 0.5, -1.2)
    sensor = radar(
        position_mapping=(0, 2), ndim_state=4, position=StateVector([0.0, 0.0]), rpm=60.0,
        fov_angle=0.1, dwell_centre=StateVector([2.9]), noise_covar=noise, pointings=listed,
    )  # fmt: skip
    sensor.timestamp = ssm.EPOCH
    then = ssm.EPOCH + timedelta(seconds=1)
    (generator,) = sensor.actions(then)
    actions = list(generator)
    assert len(actions) == len(listed)
    for b, action in zip(listed, actions, strict=True):
        assert abs(math.remainder(float(action.target_value) - b, 2 * math.pi)) < 1e-12
        copy = deepcopy(sensor)
        copy.add_actions((action,))
        copy.act(then)
        # timedelta's 1 us resolution: the rotation stops within 2 pi 1e-6 rad.
        assert abs(math.remainder(float(copy.dwell_centre[0, 0]) - b, 2 * math.pi)) < 1e-5
    # -3.0 from 2.9 is 0.38 rad the short way (increasing), not 5.9 rad back.
    assert actions[1].increasing_angle is True


def test_beam_pointings_keep_one_per_covered_set_within_range():
    pv = np.array([0.0, 0.0, 0.0, 0.0])
    bearings = np.array([0.0, 0.03, 1.0, 2.0, -3.12, 3.12])
    ranges = np.array([1000.0, 2000.0, 1500.0, 50_000.0, 800.0, 900.0])
    X = np.zeros((6, 4))
    X[:, 0], X[:, 2] = ranges * np.cos(bearings), ranges * np.sin(bearings)
    out = ssm.beam_pointings(0.1, 20_000.0, pv, X)
    # Tracks 0 and 1 (0.03 rad apart) are covered together from either: one pointing; track 3
    # is out of range; 4 and 5 are 0.043 rad apart across the cut: one pointing.
    assert [p.track for p in out] == [0, 2, 4]
    assert [p.covered for p in out] == [(0, 1), (2,), (4, 5)]
    np.testing.assert_allclose([p.bearing for p in out], bearings[[0, 2, 4]], atol=1e-12)
    assert ssm.beam_pointings(0.01, 20_000.0, pv, X)[1].covered == (1,)


def test_manager_points_every_beam_at_the_one_uncertain_track():
    """Track 7 is 1 km uncertain, track 8 known to 1 m: Stone Soup's reward (the drop in the
    covariance's Frobenius norm) is largest on 7 for every beam, even after the others'
    updates; each beam points from its platform's next position at 7's prediction F x."""
    a, b = np.array([6000.0, 0.0, 5000.0, 0.0]), np.array([2000.0, 0.0, 3000.0, 0.0])
    tracks = TrackSet(0, 0.0, "ekf", tracks=(_track(7, a, 1e6), _track(8, b, 1.0)))
    manager = ssm.StoneSoupBeamManager(SCENARIO_B)
    d = manager.decide(0, tracks, PLATFORMS_B)
    assert [c.track_id for c in d.beams] == [7, 7, 7]
    for c, pid in zip(d.beams, ("p1", "p2", "p3"), strict=True):
        assert c.bearing == pytest.approx(_bearing_from(pid, a), abs=1e-12)
    assert [(c.platform_id, c.heading_change, c.speed_change) for c in d.commands] == [
        ("p1", 0.0, 0.0), ("p2", 0.0, 0.0), ("p3", 0.0, 0.0)
    ]  # fmt: skip
    # 2 pointings per beam: the joint brute force scored 2^3 configurations.
    assert manager.configurations == 8


def test_joint_brute_force_spreads_beams_that_alone_would_share_a_track():
    """Track 1 is 2 km uncertain, track 2 1 km: each beam alone gains most on track 1 (so with
    ``candidates=1``, the pointings ranked alone, all three serve it), but a second update
    of the same track gains less than a first one of track 2: the joint brute force over
    2^3 configurations serves both (measured: beams 2, 1, 2)."""
    a, b = np.array([6000.0, 0.0, 5000.0, 0.0]), np.array([2000.0, 0.0, 5000.0, 0.0])
    tracks = TrackSet(0, 0.0, "ekf", tracks=(_track(1, a, 4e6), _track(2, b, 1e6)))
    alone = ssm.StoneSoupBeamManager(SCENARIO_B, candidates=1).decide(0, tracks, PLATFORMS_B)
    assert [c.track_id for c in alone.beams] == [1, 1, 1]
    joint = ssm.StoneSoupBeamManager(SCENARIO_B).decide(0, tracks, PLATFORMS_B)
    assert [c.track_id for c in joint.beams] == [2, 1, 2]


def test_pruning_keeps_the_best_pointings_alone():
    """With ``candidates=1`` each beam keeps only its best pointing alone, so all three point
    at the most uncertain of three tracks; 3 x 3 single rewards and 1 joint configuration."""
    means = [np.array([6000.0, 0.0, 5000.0, 0.0]), np.array([2000.0, 0.0, 5000.0, 0.0]),
             np.array([7000.0, 0.0, 1000.0, 0.0])]  # fmt: skip
    tracks = TrackSet(0, 0.0, "ekf", tracks=tuple(
        _track(i + 1, m, v) for i, (m, v) in enumerate(zip(means, (1e4, 1e6, 1e2), strict=True))
    ))  # fmt: skip
    manager = ssm.StoneSoupBeamManager(SCENARIO_B, candidates=1)
    d = manager.decide(0, tracks, PLATFORMS_B)
    assert [c.track_id for c in d.beams] == [2, 2, 2]
    assert manager.configurations == 3 * 3 + 1
    with pytest.raises(ValueError, match="candidates"):
        ssm.StoneSoupBeamManager(SCENARIO_B, candidates=0)


def test_manager_sweeps_without_confirmed_tracks():
    """No confirmed track: each beam starts along its platform's heading and moves one beam
    width (0.1 rad) per epoch, as our planner's sweep; tentative tracks do not count."""
    mean = np.array([5000.0, 0, 5000, 0])
    tentative = TrackEstimate(3, "tentative", mean, np.eye(4), mean, np.eye(4))
    manager = ssm.StoneSoupBeamManager(SCENARIO_B)
    first = manager.decide(0, TrackSet(0, 0.0, "ekf", tracks=(tentative,)), PLATFORMS_B)
    second = manager.decide(1, TrackSet(1, 1.0, "ekf"), PLATFORMS_B)
    headings = [s.heading for s in PLATFORMS_B]  # pi, pi, pi / 2
    np.testing.assert_allclose([c.bearing for c in first.beams], np.remainder(
        np.array(headings) + math.pi, 2 * math.pi) - math.pi, atol=1e-12)  # fmt: skip
    np.testing.assert_allclose(
        [c.bearing for c in second.beams], [-math.pi + 0.1, -math.pi + 0.1, math.pi / 2 + 0.1]
    )
    assert all(c.track_id == -1 for c in first.beams + second.beams)
    assert manager.configurations == 0


def test_the_three_strategies_run_paired_on_a_short_scenario(capsys):
    """Scenario (b) cut to 3 epochs, one run: every strategy yields a GOSPA within
    (0, c sqrt(N + tracks)) and missed / false counts within range, one decision per epoch;
    a run repeats bit for bit; the printout names every strategy and both paired differences."""
    short = SCENARIO_B.model_copy(update={"steps": 3})
    c = mt.compare_managers(short, [0], jobs=1)
    assert list(c.gospa) == list(mt.MANAGERS)
    for s in mt.MANAGERS:
        g = c.gospa[s]
        assert g.shape == (1,) and 0.0 < g[0] < 500.0 * math.sqrt(5 + 50)
        assert 0.0 <= c.missed[s] <= 5.0 and c.false[s] >= 0.0
        assert c.decide_s[s] > 0.0
    mt.print_managers(short, c)
    out = capsys.readouterr().out
    assert out.count(" m  (missed ") == 3 and out.count("- GOSPA(stonesoup) = ") == 2
    again = mt.run_manager((short, 0, "stonesoup", mt.DEFAULT_CANDIDATES))
    assert again.gospa == c.gospa["stonesoup"][0] and again.epochs == 3
    with pytest.raises(ValueError, match="strategy"):
        mt.run_manager((short, 0, "greedy", 4))


def test_paired_difference_and_its_interval():
    """Part 2 compares strategies by paired differences run by run (common random numbers):
    differences -10, -20, 0, -30 m: mean -15 m, sd 12.91 m, so the 95 % Student-t interval is
    -15 +- t(0.975, 3) 12.91 / 2 = -15 +- 20.54 m: not resolved."""
    ga, gb = np.array([90.0, 100.0, 110.0, 120.0]), np.array([100.0, 120.0, 110.0, 150.0])
    c = mt.ManagerComparison(
        runs=[0, 1, 2, 3],
        gospa={"planner": ga, "hold_course": gb, "stonesoup": gb},
        decide_s=dict.fromkeys(mt.MANAGERS, 0.01),
    )
    d = c.paired("planner", "stonesoup")
    assert d.mean == pytest.approx(-15.0) and d.runs == 4
    half = 3.1824463052837078 * np.std(ga - gb, ddof=1) / 2.0
    assert half == pytest.approx(20.54, abs=0.01)
    assert (d.low, d.high) == pytest.approx((-15.0 - half, -15.0 + half))
    assert not d.resolved
    same = c.paired("hold_course", "stonesoup")
    assert (same.mean, same.low, same.high) == (0.0, 0.0, 0.0)
    m, s = c.mean_se("planner")
    assert m == pytest.approx(105.0) and s == pytest.approx(np.std(ga, ddof=1) / 2.0)


# --- issue 28: the full tracker step, paired ratios, the scale table, the crowded check -------


def test_paired_speedup_is_the_median_of_per_run_ratios():
    """Per-run ratios 10, 20 and 60 (theirs / ours, same run): median 20x, while the ratio of
    total times would be 30x and p10 / p90 of the runs 12x / 52x."""
    ours = np.full((3, 2), 1e-3)
    theirs = np.array([[1e-2, 1e-2], [2e-2, 2e-2], [6e-2, 6e-2]])
    c = mt.TrackerComparison(
        seeds=[1, 2, 3], gospa_ours=np.zeros(3), gospa_theirs=np.zeros(3),
        tracks_ours=np.full(3, 3.0), tracks_theirs=np.full(3, 4.0),
        times_ours=ours, times_theirs=theirs,
    )  # fmt: skip
    np.testing.assert_allclose(c.ratios, [10.0, 20.0, 60.0])
    assert c.paired_speedup == pytest.approx(20.0)
    lo, hi = c.spread()
    assert lo == pytest.approx(12.0) and hi == pytest.approx(52.0)
    j = mt.JPDAComparison(
        seeds=[1, 2, 3], n_targets=[3, 4, 5], gospa_ours=np.zeros(3),
        gospa_theirs=np.zeros(3), max_state_diff=np.zeros(3), times_ours=ours,
        times_theirs=theirs,
    )  # fmt: skip
    assert j.paired_speedup == pytest.approx(20.0) and j.speedup == pytest.approx(30.0)


def test_tracker_comparison_times_the_trackers_without_changing_them():
    """Two runs of 4 scans: the timed steppers report what ``run_ours`` / ``run_stonesoup``
    report, one time per scan each: ours bit for bit, Stone Soup's to 1e-6 m (it iterates
    sets of tracks and detections, whose order follows object addresses: its sums differ at
    round-off from one run to the next, measured 2e-8 m)."""
    c = mt.compare_trackers([3000, 3001], n_scans=4, warm_up=False)
    mtt = mt.tracking_module()
    assert c.times_ours.shape == c.times_theirs.shape == (2, 4)
    assert np.all(c.times_ours > 0) and np.all(c.times_theirs > 0)
    for i, seed in enumerate((3000, 3001)):
        world = mt.replace_scans(mtt.simulate("radar", "drawn", seed, mt.TRACKER_TARGETS), 4)
        assert c.gospa_ours[i] == mtt.mean_gospa(world, mtt.run_ours("radar", world))
        theirs = mtt.mean_gospa(world, mtt.run_stonesoup("radar", world))
        assert c.gospa_theirs[i] == pytest.approx(theirs, rel=0, abs=1e-6)
    assert np.all(c.tracks_ours >= 1.0)


def test_our_tracker_equals_stonesoup_exact_jpda_on_an_easy_scene():
    """3 targets, 12 scans (before the crossing), no initiation: our tracker's GOSPA equals
    that of Stone Soup's exact JPDA (EHM) to 1e-4 m (its finite-difference Jacobian), so the
    crowded check compares association, not conventions."""
    pytest.importorskip("pyehm")
    c = mt.check_crowded(replace(SC, n_steps=12), seeds=(2000,), n=3)
    assert abs(c.ours[0] - c.exact[0]) < 1e-4 and c.equal
    assert 1.0 < c.ours[0] < SC.cutoff
    # No track comes near deletion here: the tracker as configured gives the same figure.
    assert c.deletions == [{}] and c.managed[0] == c.ours[0]


_SCALE = mt._scale_module()


@pytest.mark.parametrize(
    ("n", "layout", "radars"),
    [(3, "spread", 1), (10, "spread", 4), (100, "spread", 16), (300, "spread", 49),
     (10, "crowded", 1), (30, "crowded", 4), (1000, "crowded", 100)],
)  # fmt: skip
def test_scale_scene_radars_and_targets(n, layout, radars):
    scene = _SCALE.build(n, layout, 10.0, seed=1, steps=2)
    assert len(scene.radars) == radars and scene.prior_means.shape == (n, 4)
    assert scene.truth.shape == (3, n, 4) and len(scene.scans) == 2
    assert all(len(row) == radars for row in scene.scans)
    if layout == "crowded":  # each clump starts in its 1 km box, 4 km east of its radar
        centres = np.array([[pv[0] + _SCALE.CLUMP_OFFSET, pv[2]] for _, _, pv, _ in scene.radars])
        off = scene.truth[0][:, [0, 2]] - centres[np.arange(n) % radars]
        assert np.all(np.abs(off) <= 0.5 * _SCALE.CLUMP_BOX)


def test_scale_scene_clutter_rate():
    """One radar, 3 targets, 100 false alarms per scan over 20 scans: the mean scan holds 100 +
    at most 3 detections; the Poisson sd of the 20-scan mean is 2.2, so within 9 (4 SE)."""
    scene = _SCALE.build(3, "spread", 100.0, seed=4, steps=20)
    sizes = np.array([len(row[0]) for row in scene.scans])
    assert abs(sizes.mean() - 100.0 - 0.9 * 3) < 9.0
    again = _SCALE.build(3, "spread", 100.0, seed=4, steps=20)
    assert all(np.array_equal(a[0], b[0]) for a, b in zip(scene.scans, again.scans, strict=True))
    with pytest.raises(ValueError, match="layout"):
        _SCALE.build(3, "diagonal", 10.0)


def test_budget_stops_an_epoch_and_says_so():
    """A step of 0.3 s under a 0.5 s budget: one epoch finishes, the second is cut."""
    import time as _time

    got = _SCALE.time_epochs(lambda k: _time.sleep(0.3), 5, 0.5)
    assert got.over and len(got.times) == 1 and got.times[0] >= 0.3
    text = got.cell(0.5)
    assert (
        text == f"{got.times[0] * 1e3:.1f} ms (1 epochs, then over budget (POINT_BUDGET_S=0.5 s))"
    )
    assert _SCALE.PointTime([], over=True).cell(2.0) == "over budget (POINT_BUDGET_S=2 s)"


def test_scale_table_names_every_point_it_does_not_run(monkeypatch):
    """An implementation over budget at n = 3 is not started at n = 10: its cell says so;
    the other one runs both."""
    import time as _time

    def make_step(name, scene):
        if name == "slow":
            return lambda k: _time.sleep(0.4)
        return lambda k: None

    monkeypatch.setattr(_SCALE, "make_step", make_step)
    rows = _SCALE.scale_table([10, 3], ["spread"], [10.0], ["fast", "slow"], 0.2, 2)
    assert [r.n_targets for r in rows] == [3, 10]
    assert rows[0].cells["slow"].cell(0.2) == "over budget (POINT_BUDGET_S=0.2 s)"
    assert rows[1].cells["slow"].cell(0.2) == "not run: over budget at n=3 (POINT_BUDGET_S=0.2 s)"
    assert all(len(r.cells["fast"].times) == 2 for r in rows)
