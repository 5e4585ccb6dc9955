"""The multi-target planner's work shared across candidates and platforms gives the decisions
it gave without (bit for bit):

- decisions on scenes of benchmarks/planning_scale.py (12 tracks, 4 platforms: MRE over one
  and two legs, the worst track, PCRLB; 3 tracks and 5 platforms whose beams share tracks)
  equal those measured before, to the last bit, with fewer cost evaluations where the
  platforms' beams serve different tracks (each searched once);
- every track's detection factor from one beam at once equals track by track, and the MRE
  pair costs of all tracks at once equal pair by pair (random geometries, all criteria);
- which platforms interact: those whose supports share a track.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest

from activetrack.models.clutter import ClutteredSensor
from activetrack.models.sensors import BearingSensor, RangeBearingSensor
from activetrack.planning.across_targets import _Sensor
from activetrack.planning.assignment import NO_MISSES, MissedLooks, mre_pair_costs
from activetrack.planning.criteria import get_criterion
from activetrack.planning.multisensor import interactions
from activetrack.planning.selection import TargetPrediction

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "planning_scale.py"
_spec = importlib.util.spec_from_file_location("bench_planning_scale", _PATH)
assert _spec is not None and _spec.loader is not None
ps = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = ps
_spec.loader.exec_module(ps)

_GATE = {"aggregate": "weighted_sum", "assignment": "mre", "clutter_gate": "innovation"}
H = 0.1512618685061752  # the turn most commands make here [rad]
V, W = 9.629629629629619, -8.148148148148152  # speed changes [m/s]
# name: (tracks, platforms, planner overrides), the commands (heading, speed change), the beams
# (bearing, track), the aggregate cost, cost evaluations (before the shared work: 287, 12054,
# 287, 238, 369). All measured on main before the shared work (f5510a9).
DECISIONS = {
    "mre_r1": (
        (12, 4, {}),
        [(H, V), (H, V), (H, W), (H, V)],
        [
            (3.0594983524123545, 11),
            (-1.7361940433903231, 9),
            (0.14546592986431986, 8),
            (1.6730162366678494, 1),
        ],
        5973.827879736004,
        164,
    ),
    "mre_r2": (
        (12, 4, {"horizon": 2}),
        [(H, V)] * 4,
        [
            (3.0594983524123545, 11),
            (-1.7361940433903231, 9),
            (0.14839172353996904, 8),
            (1.6730162366678494, 1),
        ],
        5973.827835005296,
        6888,
    ),
    "mre_worst": (  # not a sum over tracks: every platform interacts with every other
        (12, 4, {"targets": {**_GATE, "aggregate": "worst"}}),
        [(H, V), (H, V), (H, W), (H, V)],
        [
            (3.0594983524123545, 11),
            (-1.7361940433903231, 9),
            (0.14546592986431986, 8),
            (1.6730162366678494, 1),
        ],
        525.0,
        287,
    ),
    "pcrlb": (
        (
            12,
            4,
            {
                "cost": "pcrlb",
                "criterion": "b_k",
                "search": "quadrant",
                "mc_samples": 50,
                "targets": {"aggregate": "weighted_sum", "assignment": "mre"},
            },
        ),
        [
            (0.15707963267948966, -10.0),
            (0.15707963267948966, -10.0),
            (0.15707963267948966, 10.0),
            (0.14726215563702155, 10.0),
        ],
        [
            (-2.7052684953254924, 3),
            (-1.178736690592298, 11),
            (-0.3694478360876185, 1),
            (2.0258090602506487, 0),
        ],
        127.3577412552399,
        136,
    ),
    "mre_r1_shared": (  # beams on tracks 1, 2, 0, 2, 1 during the search: two components
        (3, 5, {}),
        [(H, -9.629629629629633), (H, V), (H, -9.629629629629633), (H, V), (H, V)],
        [
            (-2.873547841875877, 1),
            (-2.047649681579232, 2),
            (-0.796573034691569, 0),
            (0.8353268801872493, 2),
            (1.709247825489436, 1),
        ],
        1196.410905556617,
        287,
    ),
}


@pytest.mark.parametrize("name", sorted(DECISIONS))
def test_decisions_are_those_before_the_shared_work(name):
    (T, P, planner), commands, beams, aggregate, evaluations = DECISIONS[name]
    sc = ps.scale_scene(T, P, planner=planner)
    d = ps.decide(sc, ps.confirmed_tracks(sc), ps.snapshots(sc))
    assert [(c.heading_change, c.speed_change) for c in d.commands] == commands
    assert [(b.bearing, b.track_id) for b in d.beams] == beams
    assert d.report is not None
    assert d.report.predicted_costs[0] == aggregate
    assert d.report.evaluations == evaluations


def test_platforms_serving_different_tracks_are_searched_once():
    # (b)'s sector search with 3 levels: 16 + 12 + 12 + 1 = 41 evaluations per platform.
    for name in ("mre_r1", "mre_worst"):
        (T, P, planner), *_ = DECISIONS[name]
        sc = ps.scale_scene(T, P, planner=planner)
        d = ps.decide(sc, ps.confirmed_tracks(sc), ps.snapshots(sc))
        assert d.report is not None
        searches = d.report.evaluations / 41
        assert searches == (P if name == "mre_r1" else 2 * P - 1)


def _tracks(rng: np.random.Generator, T: int) -> tuple[np.ndarray, np.ndarray]:
    xs = np.column_stack(
        [
            rng.uniform(-2e4, 2e4, T),
            rng.normal(0, 100, T),
            rng.uniform(-2e4, 2e4, T),
            rng.normal(0, 100, T),
        ]
    )
    A = rng.normal(size=(T, 4, 4)) * np.array([30.0, 3.0, 30.0, 3.0])
    Ps = A @ np.swapaxes(A, -1, -2) + np.eye(4)
    return xs, 0.5 * (Ps + np.swapaxes(Ps, -1, -2))


def _radar(kind: int, **kw) -> ClutteredSensor:
    if kind == 0:
        return ClutteredSensor(BearingSensor(sigma=0.0016, pd=0.9, r_min=100.0), 10.0, **kw)
    base = RangeBearingSensor(sigma_r=30.0, sigma_b=0.0016, pd=0.8, r_min=100.0, r_max=2e4)
    return ClutteredSensor(base, 2e-4, **kw)


def test_detections_of_all_tracks_equal_track_by_track():
    rng = np.random.default_rng(1)
    seen: list[float] = []
    for trial in range(60):
        model = _radar(
            trial % 2,
            beam_width=0.1 if trial % 5 else None,
            fov_width=1.5 if trial % 3 == 0 else None,
            clutter_gate="innovation" if trial % 4 < 2 else "measurement",
        )
        s = _Sensor("s", 0, model, model.information_factor)
        T = int(rng.integers(1, 30))
        xs, Ps = _tracks(rng, T)
        pv = np.array([rng.uniform(-2e4, 2e4), 50.0, rng.uniform(-2e4, 2e4), -30.0])
        missed = [
            NO_MISSES
            if rng.random() < 0.6
            else MissedLooks(rng.uniform(0.05, 0.9), rng.uniform(0.1, 0.9), rng.uniform(1e2, 5e3))
            for _ in range(T)
        ]
        want = [float(s.detection(xs[t], pv, Ps[t], missed[t])) for t in range(T)]
        got = s.detections(xs, pv, Ps, missed)
        assert got.tolist() == want  # bit for bit
        seen.extend(want)
    assert 0.3 < np.mean(np.array(seen) > 0.0) < 1.0 and max(seen) <= 1.0  # looks and misses


@pytest.mark.parametrize("criterion", ["trace", "det_pos", "range", "heading"])
def test_mre_pair_costs_of_all_tracks_equal_pair_by_pair(criterion):
    rng = np.random.default_rng(3)
    F = np.eye(4)
    F[0, 1] = F[2, 3] = 1.0
    Q = np.diag([6.25, 25.0, 6.25, 25.0])
    crit = get_criterion(criterion)
    for _ in range(20):
        T, S = int(rng.integers(1, 20)), int(rng.integers(1, 5))
        xs, Ps = _tracks(rng, T)
        preds = [TargetPrediction.from_posterior(x, P, F, Q) for x, P in zip(xs, Ps, strict=True)]
        sensors = [_radar(s % 2, beam_width=0.1) for s in range(S)]
        pvs = np.column_stack(
            [rng.uniform(-2e4, 2e4, S), np.full(S, 50.0), rng.uniform(-2e4, 2e4, S), -np.ones(S)]
        )
        d = rng.uniform(0.0, 1.0, (S, T)) * (rng.random((S, T)) < 0.8)  # some looks miss
        C, c0 = mre_pair_costs(preds, sensors, pvs, d, criterion)
        for t, p in enumerate(preds):
            assert c0[t] == float(crit.of_covariance(p.F @ p.P @ p.F.T + p.Q, p.x))
            for s, sensor in enumerate(sensors):
                P1 = p.after_look(sensor, pvs[s], float(d[s, t])).P
                want = float(crit.of_covariance(p.F @ P1 @ p.F.T + p.Q, p.x))
                assert C[s, t] == min(want, c0[t])  # bit for bit


def test_platforms_interact_when_their_supports_share_a_track():
    a, b, c = (np.array(m, dtype=bool) for m in ([1, 0, 0], [0, 1, 0], [0, 1, 1]))
    got = interactions([a, b, c, None, np.zeros(3, dtype=bool)], 5)
    want = np.array(
        [
            [1, 0, 0, 1, 0],
            [0, 1, 1, 1, 0],
            [0, 1, 1, 1, 0],
            [1, 1, 1, 1, 1],  # None: every state, so every platform
            [0, 0, 0, 1, 1],  # no track at all (e.g. no sensor): only with None
        ],
        dtype=bool,
    )
    assert np.array_equal(got, want)
    assert interactions(None, 3).all()
    with pytest.raises(ValueError, match="supports must hold one entry per platform"):
        interactions([a, b], 3)
    with pytest.raises(ValueError, match="supports must be"):
        interactions([a, np.ones(4, dtype=bool)], 2)


def test_predictions_of_all_tracks_equal_one_by_one():
    rng = np.random.default_rng(5)
    F = np.eye(4)
    F[0, 1] = F[2, 3] = 2.0
    Q = np.array([[1.0, 0.5, 0, 0], [0.5, 1.0, 0, 0], [0, 0, 1.0, 0.5], [0, 0, 0.5, 1.0]])
    xs, Ps = _tracks(rng, 25)
    many = TargetPrediction.from_posteriors(list(xs), list(Ps), F, Q)
    for x, P, p in zip(xs, Ps, many, strict=True):
        one = TargetPrediction.from_posterior(x, P, F, Q)
        assert np.array_equal(p.x, one.x) and np.array_equal(p.P, one.P)  # bit for bit
    assert TargetPrediction.from_posteriors([], [], F, Q) == []
    bad = Ps.copy()
    bad[3] = -bad[3]
    with pytest.raises(ValueError, match="P_pred must be symmetric positive definite"):
        TargetPrediction.from_posteriors(list(xs), list(bad), F, Q)
