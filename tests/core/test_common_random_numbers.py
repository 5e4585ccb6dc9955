"""Common random numbers (activetrack.simulation.streams): the world does not depend on the
policy. Targets move the same under every policy; a sensor that looks at the same place at an
epoch gets the same detections, noise and clutter whatever it or the others did before."""

import numpy as np
import pytest

from activetrack.closed_loop.components import build_simulator, component_rngs
from activetrack.closed_loop.loop import run_once
from activetrack.data import BeamCommand
from activetrack.scenarios import ScenarioError, load_scenario, with_changes

RADARS = "scenarios/mt_radars_beams.yaml"
CROSSING = "scenarios/mt_bearings_crossing.yaml"


def _sim(scenario, run=3):
    return build_simulator(scenario, component_rngs(scenario.seed, run)[0])


def _scan_of(scans, sensor_id):
    return next(s for s in scans if s.sensor_id == sensor_id)


@pytest.mark.parametrize("path", [RADARS, CROSSING])
def test_targets_move_the_same_under_every_policy(path):
    base = with_changes(load_scenario(path), steps=12)
    planner = run_once(base, run=5)
    hold = run_once(with_changes(base, planner={"enabled": False}), run=5)
    rand = run_once(with_changes(base, planner={"targets": {"assignment": "random"}}), run=5)
    # the policies did act differently ...
    assert not np.array_equal(planner.platform_paths, hold.platform_paths)
    # ... on the same world: truth equal bit for bit, NaN where a target is absent
    np.testing.assert_array_equal(planner.truth, hold.truth)
    np.testing.assert_array_equal(planner.truth, rand.truth)


def test_a_beam_pointed_at_the_same_place_gets_the_same_scan_whatever_came_before():
    scenario = load_scenario(RADARS)
    a, b = _sim(scenario), _sim(scenario)
    steerable = a.steerable_ids
    assert steerable
    sid = steerable[0]
    # epoch 1: the two worlds' beams point in opposite directions
    a.apply_beam(BeamCommand(sid, 0, 0.3))
    b.apply_beam(BeamCommand(sid, 0, 0.3 + np.pi))
    scans_a, scans_b = a.advance(), b.advance()
    assert not np.array_equal(_scan_of(scans_a, sid).fov.centre, _scan_of(scans_b, sid).fov.centre)
    # epoch 2: the same direction: the same scan, detections, noise, clutter and order
    for sim in (a, b):
        sim.apply_beam(BeamCommand(sid, 1, -1.1))
    scans_a, scans_b = a.advance(), b.advance()
    for sa, sb in zip(scans_a, scans_b, strict=True):
        assert sa.sensor_id == sb.sensor_id
        np.testing.assert_array_equal(sa.Z, sb.Z)
    assert a.last_truth == b.last_truth


def test_a_sensor_left_out_does_not_shift_the_others_draws():
    scenario = load_scenario(CROSSING)
    every, some = _sim(scenario), _sim(scenario)
    sensors = tuple(every.sensors)
    assert len(sensors) >= 2
    some.apply_selection(sensors[:1])
    for _ in range(5):
        all_scans, some_scans = every.advance(), some.advance()
        assert [s.sensor_id for s in some_scans] == [sensors[0]]
        np.testing.assert_array_equal(_scan_of(all_scans, sensors[0]).Z, some_scans[0].Z)
        np.testing.assert_array_equal(every.truth_array(), some.truth_array())


def test_runs_differ_and_repeat():
    scenario = load_scenario(RADARS)
    one, again, other = _sim(scenario, 1), _sim(scenario, 1), _sim(scenario, 2)
    for _ in range(3):
        z1, z1b = one.advance(), again.advance()
        other.advance()
    np.testing.assert_array_equal(one.truth_array(), again.truth_array())
    assert all(np.array_equal(p.Z, q.Z) for p, q in zip(z1, z1b, strict=True))
    assert not np.array_equal(one.truth_array(), other.truth_array())


def test_sequential_streams_draw_from_the_one_generator_in_the_documented_order():
    """One target, one sensor, no clutter: epoch 1 is the prior draw, one motion draw, one
    detection draw and (detected) one noise draw, in that order from the one generator."""
    scenario = with_changes(
        load_scenario("scenarios/ramdaras_case2.yaml"), steps=2, random_streams="sequential"
    )
    sim = build_simulator(scenario, np.random.default_rng(17))
    rng = np.random.default_rng(17)
    target = sim.targets[0]
    _, sensor = next(iter(sim.sensors.values()))
    x0 = target.draw_start(rng)  # its initial_state: no draw
    np.testing.assert_array_equal(sim.states[0], x0)
    x1 = target.model.sample(x0, scenario.dt, rng)
    scans = sim.advance()
    np.testing.assert_array_equal(sim.states[0], x1)
    detected = rng.random() < sensor.pd
    assert len(scans[0].Z) == int(detected)
    if detected:
        np.testing.assert_array_equal(
            scans[0].Z[0], sensor.sample(target.model.kinematics(x1), scans[0].sensor_pv, rng)
        )


def test_random_streams_must_be_common_or_sequential():
    with pytest.raises(ScenarioError, match="random_streams"):
        with_changes(load_scenario(RADARS), random_streams="shared")


def test_one_generator_is_not_common_random_numbers():
    """Why ``common`` is the default: with one generator, a policy that looks elsewhere
    consumes other draws and the targets' own motion diverges."""
    base = with_changes(load_scenario(RADARS), steps=12, random_streams="sequential")
    planner = run_once(base, run=5)
    hold = run_once(with_changes(base, planner={"enabled": False}), run=5)
    assert not np.array_equal(planner.truth, hold.truth)
