"""Simulator and tracker of the closed loop (one target): kinematics, clamping, detection,
determinism."""

import math

import numpy as np
import pytest

from activetrack.closed_loop.components import build_simulator, build_tracker
from activetrack.data import Command
from activetrack.scenarios import load_scenario, parse_scenario

HERNANDEZ = "scenarios/hernandez_1sensor_single.yaml"


@pytest.fixture
def scenario():
    return load_scenario(HERNANDEZ)


def _with(scenario, **changes):
    data = scenario.model_dump()
    for path, value in changes.items():
        node = data
        *head, last = path.split(".")
        for key in head:
            node = node[int(key)] if key.isdigit() else node[key]
        node[last] = value
    return parse_scenario(data)


def test_platform_flies_constant_velocity_legs(scenario):
    sim = build_simulator(scenario, np.random.default_rng(1))
    sim.advance()
    np.testing.assert_allclose(sim.platforms["p1"].pv, [1800 - 200, -40, 2000 - 200, -40])
    assert sim.time == 5.0 and sim.epoch == 1


def test_command_within_limits_is_applied_exactly(scenario):
    sim = build_simulator(scenario, np.random.default_rng(1))
    res = sim.apply_command(Command("p1", 0, 0.2, 5.0))
    assert not res.clamped
    v0 = math.hypot(40, 40)
    assert res.command.commanded_speed == pytest.approx(v0 + 5.0)
    heading0 = math.atan2(-40, -40)
    assert res.command.commanded_heading == pytest.approx(heading0 + 0.2)
    pv = sim.platforms["p1"].pv
    assert math.hypot(pv[1], pv[3]) == pytest.approx(v0 + 5.0)


def test_command_outside_limits_is_clamped_and_reported(scenario):
    sim = build_simulator(scenario, np.random.default_rng(1))
    res = sim.apply_command(Command("p1", 0, 1.0, -30.0))
    assert res.clamped
    assert "heading_change" in res.message and "speed" in res.message
    assert res.command.heading_change == pytest.approx(math.pi / 10)
    # dv clamped to -10, then speed 46.6 clamped up to v_min = 50
    assert res.command.commanded_speed == pytest.approx(50.0)


@pytest.mark.parametrize(
    "cmd, field",
    [
        (Command("nope", 0, 0.0, 0.0), "platform_id"),
        (Command("p1", 3, 0.0, 0.0), "epoch"),
        (Command("p1", 0, math.nan, 0.0), "heading_change"),
    ],
)
def test_bad_commands_are_rejected(scenario, cmd, field):
    sim = build_simulator(scenario, np.random.default_rng(1))
    with pytest.raises(ValueError, match=field):
        sim.apply_command(cmd)


def test_no_detection_inside_minimum_range(scenario):
    # Put the platform on top of the target: inside r_min = 1000 m there is no detection.
    sc = _with(scenario, **{"platforms.0.initial_state": [1000.0, -40.0, 1000.0, -40.0]})
    sim = build_simulator(sc, np.random.default_rng(2))
    (scan,) = sim.advance()
    assert scan.Z.shape == (0, 1) and scan.sensor_id == "s1"


def test_detection_rate_follows_pd(scenario):
    sc = _with(scenario, **{"platforms.0.sensors.0.pd": 0.3, "steps": 2000})
    sim = build_simulator(sc, np.random.default_rng(3))
    hits = [len(sim.advance()[0].Z) > 0 for _ in range(2000)]
    # Binomial(2000, 0.3): sd = 0.0102; 4 sd.
    assert abs(np.mean(hits) - 0.3) < 0.041


def test_same_seed_same_measurements(scenario):
    a = build_simulator(scenario, np.random.default_rng(7))
    b = build_simulator(scenario, np.random.default_rng(7))
    for _ in range(5):
        za = [scan.Z for scan in a.advance()]
        zb = [scan.Z for scan in b.advance()]
        assert all(np.array_equal(x, y) for x, y in zip(za, zb, strict=True))


def test_selection_limits_which_sensors_measure(scenario):
    sim = build_simulator(scenario, np.random.default_rng(1))
    sim.apply_selection([])
    assert sim.advance() == []
    with pytest.raises(ValueError, match="sensor ids"):
        sim.apply_selection(["s9"])


def test_tracker_pf_snapshot_samples(scenario):
    sc = _with(scenario, **{"tracker.particles": 2000, "tracker.planner_samples": 500})
    sim = build_simulator(sc, np.random.default_rng(1))
    trk = build_tracker(sc, np.random.default_rng(2))
    (snap,) = trk.snapshot().tracks
    assert snap.samples.shape == (500, 4)
    # Samples of the prior N(mean, diag(10, 1, 10, 1)): mean within 4 standard errors.
    se = np.sqrt(np.array([10, 1, 10, 1]) / 500)
    assert np.all(np.abs(snap.samples.mean(axis=0) - snap.mean) < 4 * se + 4 * se)
    tracks = trk.step(1, sim.time + 5.0, sim.advance())
    (snap,) = tracks.tracks
    assert tracks.updates == 1 and 1 <= snap.ess <= 2000
    assert np.all(np.linalg.eigvalsh(snap.cov) > 0)


def test_covariance_ellipse_axes():
    from activetrack.geometry import covariance_ellipse

    # Principal axes 3 and 1 (std), rotated by 30 degrees, 2-sigma outline.
    a = np.deg2rad(30)
    V = np.array([[np.cos(a), -np.sin(a)], [np.sin(a), np.cos(a)]])
    P = V @ np.diag([9.0, 1.0]) @ V.T
    pts = covariance_ellipse([10.0, -5.0], P, scale=2.0, n_points=721)
    d = pts - [10.0, -5.0]
    r = np.hypot(d[:, 0], d[:, 1])
    assert r.max() == pytest.approx(6.0, rel=1e-4) and r.min() == pytest.approx(2.0, rel=1e-4)
    # Every point satisfies d^T P^-1 d = scale^2.
    m = np.einsum("ni,ij,nj->n", d, np.linalg.inv(P), d)
    np.testing.assert_allclose(m, 4.0, rtol=1e-9)
    np.testing.assert_allclose(pts[0], pts[-1])
