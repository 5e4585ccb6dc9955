"""Search versus track: the undetected-target intensity over a surveillance region, the value
of a search pointing in GOSPA units and its column in the beams' assignment
(``planner.targets.surveillance``, ``activetrack.planning.search_intensity``)."""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numpy as np
import pytest

from activetrack.closed_loop.components import build_across_targets
from activetrack.data import PlatformSnapshot, TrackEstimate, TrackSet, heading_speed
from activetrack.models.clutter import ClutteredSensor
from activetrack.models.sensors import RangeBearingSensor
from activetrack.planning.assignment import NO_MISSES, round_assignment, search_columns
from activetrack.planning.expected_gospa import GospaWeights
from activetrack.planning.gospa_rollout import FirstLegSearch, GospaRollout, Look
from activetrack.planning.search_intensity import (
    Surveillance,
    UndetectedIntensity,
    birth_odds,
    footprint,
    footprints,
    search_bearings,
    search_value,
)
from activetrack.scenarios import parse_scenario

W = GospaWeights(500.0, 2.0, 2.0)  # c^p / alpha = 125000


def _two_by_two() -> UndetectedIntensity:
    # cells of 1 m: centres (0.5, 0.5), (0.5, 1.5), (1.5, 0.5), (1.5, 1.5) (x-major)
    return UndetectedIntensity(Surveillance((0.0, 2.0, 0.0, 2.0), 0.4, 1.0), dt=2.0)


def test_intensity_by_hand_on_a_two_by_two_grid():
    u = _two_by_two()
    np.testing.assert_allclose(u.xy, [[0.5, 0.5], [0.5, 1.5], [1.5, 0.5], [1.5, 1.5]])
    np.testing.assert_array_equal(u.intensity, 0.0)
    u.predict()  # 0.4 targets/s * 2 s over 4 cells
    np.testing.assert_allclose(u.intensity, [0.2, 0.2, 0.2, 0.2])
    u.look([True, False, False, True], pd=0.9)  # a look depletes its cells by 1 - Pd
    np.testing.assert_allclose(u.intensity, [0.02, 0.2, 0.2, 0.02])
    u.predict()
    np.testing.assert_allclose(u.intensity, [0.22, 0.4, 0.4, 0.22])
    u.look([True, True, False, False], pd=0.5)
    np.testing.assert_allclose(u.intensity, [0.11, 0.2, 0.4, 0.22])
    assert u.intensity.sum() == pytest.approx(0.93)
    # a track at (0.5, 0.6) covers the cells within c = 0.5 of it: only the first
    np.testing.assert_array_equal(u.uncovered([[0.5, 0.6]], 0.5), [False, True, True, True])
    np.testing.assert_array_equal(u.uncovered(np.zeros((0, 2)), 0.5), [True] * 4)
    with pytest.raises(ValueError, match="pd must lie in"):
        u.look([True] * 4, pd=1.5)


def test_uniform_births_are_the_default_and_the_same_bits():
    # today's intensity: birth_rate dt / N per cell per epoch, written out as before
    region, rate, dt = (-5000.0, 5000.0, 0.0, 10000.0), 4.0 / 180.0, 4.0
    u = UndetectedIntensity(Surveillance(region, rate, 250.0), dt)
    same = UndetectedIntensity(Surveillance(region, rate, 250.0, "uniform"), dt)
    assert u.layers.shape == (1, 1600) and u.shifts is None
    inside = np.arange(1600) % 7 == 0
    before = np.zeros(1600)
    for _ in range(5):
        for v in (u, same):
            v.predict()
            v.look(inside, 0.9)
        before = before + np.full(1600, rate * dt / 1600)
        before = np.where(inside, before * (1.0 - 0.9), before)
    np.testing.assert_array_equal(u.intensity, before)
    np.testing.assert_array_equal(same.intensity, before)
    assert u.left == 0.0


def _edges(speed: float, edges=("west", "north")) -> UndetectedIntensity:
    # 4 x 4 cells of 250 m; 0.1 targets / s * 4 s = 0.4 per epoch, half per edge (equal
    # lengths), 0.05 per edge cell; 25 m/s * 4 s = 100 m = 0.4 cell per epoch
    return UndetectedIntensity(
        Surveillance((0.0, 1000.0, 0.0, 1000.0), 0.1, 250.0, "edges", edges, speed), 4.0
    )


def test_edge_births_drift_inward_and_conserve_their_mass():
    u = _edges(25.0)
    grid = u.birth.reshape(2, 4, 4)
    np.testing.assert_allclose(grid[0, 0, :], 0.05)  # west: x row 0
    np.testing.assert_allclose(grid[1, :, -1], 0.05)  # north: y column 3
    assert u.birth.sum() == pytest.approx(0.4)  # birth_rate dt, all of it
    assert u.shifts == ((0, pytest.approx(0.4)), (1, pytest.approx(-0.4)))
    for _ in range(3):
        u.predict()
    # west layer along x: row 0 keeps 0.6 of each epoch's mass, 0.4 moves on each epoch
    # 0.05 (1 + 0.6 + 0.36), 0.05 (0.4 + 2 * 0.6 * 0.4), 0.05 * 0.4^2, 0
    west = u.layers.reshape(2, 4, 4)[0]
    np.testing.assert_allclose(west[:, 2], [0.098, 0.044, 0.008, 0.0], atol=1e-15)
    north = u.layers.reshape(2, 4, 4)[1]
    np.testing.assert_allclose(north[1, :], [0.0, 0.008, 0.044, 0.098], atol=1e-15)
    assert u.left == 0.0 and u.intensity.sum() == pytest.approx(1.2)
    # after 10 cells of travel the first births have left: nothing lost but what left
    for _ in range(20):
        u.predict()
    assert u.left > 0.5
    assert u.intensity.sum() + u.left == pytest.approx(23 * 0.4, rel=1e-12)
    # a look depletes every layer by 1 - Pd in its footprint only
    layers, inside = u.layers.copy(), np.arange(16) < 4
    u.look(inside, 0.9)
    np.testing.assert_allclose(u.layers[:, inside], 0.1 * layers[:, inside])
    np.testing.assert_array_equal(u.layers[:, ~inside], layers[:, ~inside])
    # without a speed the births stay on their edges
    still = _edges(0.0, ("east",))
    still.predict()
    still.predict()
    np.testing.assert_allclose(still.intensity.reshape(4, 4)[-1], 0.2)
    assert still.intensity.sum() == pytest.approx(0.8) and still.shifts is None


def test_a_drift_of_more_than_a_cell_splits_between_the_two_cells_it_reaches():
    u = _edges(80.0, ("south",))  # 320 m = 1.28 cells per epoch along +y
    u.predict()
    u.predict()
    col = u.intensity.reshape(4, 4)[0]  # 0.1 per south cell per epoch
    np.testing.assert_allclose(col, [0.1, 0.072, 0.028, 0.0], atol=1e-15)
    for _ in range(3):
        u.predict()
    assert u.intensity.sum() + u.left == pytest.approx(5 * 0.4, rel=1e-12)
    assert u.left > 0.0


def test_the_birth_model_is_checked():
    region = (0.0, 1000.0, 0.0, 1000.0)
    for kwargs, field in (
        ({"births": "edge"}, "surveillance.births"),
        ({"births": "edges"}, "surveillance.edges"),
        ({"births": "edges", "edges": ("west", "west")}, "surveillance.edges"),
        ({"births": "edges", "edges": ("up",)}, "surveillance.edges"),
        ({"births": "edges", "edges": ("west",), "birth_speed": -1.0}, "birth_speed"),
        ({"births": "edges", "edges": ("west",), "birth_speed": math.nan}, "birth_speed"),
        ({"edges": ("west",)}, "need births 'edges'"),
        ({"birth_speed": 25.0}, "need births 'edges'"),
    ):
        with pytest.raises(ValueError, match=field):
            Surveillance(region, 0.1, 250.0, **kwargs)


def test_birth_odds_by_hand():
    # one 1 km cell centred at (0, 1000) holding D = 0.25 / s * 4 s = 1 target, a radar at the
    # origin (Pd 0.9, clutter 3e-4 per m rad): e = Pd D / A = 0.9e-6 per m^2; a range-bearing
    # z has |det dh/dx| = 1 / r = 1e-3, so kappa = 3e-4 * 1e-3 = 3e-7 per m^2: odds 3 (r 0.75)
    u = UndetectedIntensity(Surveillance((-500.0, 500.0, 500.0, 1500.0), 0.25, 1000.0), 4.0)
    u.predict()
    assert u.cell_area == 1e6 and u.intensity.tolist() == [1.0]
    radar = RangeBearingSensor(sigma_r=10.0, sigma_b=0.01, pd=0.9, r_max=5000.0)
    sensor = ClutteredSensor(radar, clutter_density=3e-4, beam_width=0.2)
    pv = np.zeros(4)
    np.testing.assert_allclose(birth_odds(sensor, u, pv, [True]), [3.0], rtol=1e-12)
    assert birth_odds(sensor, u, pv, [False]).tolist() == [0.0]  # not seen: no odds
    u.look([True], 0.9)  # a depleted cell: a tenth of the odds
    np.testing.assert_allclose(birth_odds(sensor, u, pv, [True]), [0.3], rtol=1e-12)
    clean = ClutteredSensor(radar, beam_width=0.2)  # no clutter: any detection is a target
    assert birth_odds(clean, u, pv, [True]).tolist() == [math.inf]
    # a position within one cell outside the region maps to its nearest cell; farther: none
    assert u.cell_of([[0.0, 1000.0], [-1400.0, 1000.0], [0.0, 2600.0]]).tolist() == [0, 0, -1]


def test_search_value_by_hand():
    # c = 500 m, p = 2, alpha = 2: c^p / alpha = 125000 m^2 per missed target
    k = GospaWeights(500.0, 2.0, 2.0).cardinality
    assert k == 125000.0
    intensity = np.array([0.11, 0.2, 0.4, 0.22])
    seen = np.array([[True, False, True, False], [False, False, False, True]])
    # Pd Lambda c^p / alpha per epoch, over 3 epochs: 0.9 * 0.51 * 125000 * 3, 0.9 * 0.22 * ...
    np.testing.assert_allclose(
        search_value(intensity, seen, 0.9, k, 3), [172125.0, 74250.0], rtol=1e-12
    )
    with pytest.raises(ValueError, match="epochs must be >= 1"):
        search_value(intensity, seen, 0.9, k, 0)


def test_a_search_column_by_hand_and_against_a_track():
    # one beam, one track whose service saves 1000 (c0 - C); two pointings of the beam
    C, c0 = np.array([[4000.0]]), np.array([5000.0])
    Cs, c0s, w = search_columns(C, c0, np.array([1.0]), np.array([[600.0, 900.0]]))
    np.testing.assert_allclose(Cs, [[4000.0, -600.0, -900.0]])
    np.testing.assert_allclose(c0s, [5000.0, 0.0, 0.0])
    np.testing.assert_allclose(w, [1.0, 1.0, 1.0])
    assert round_assignment(Cs, c0s, w, "weighted_sum").tolist() == [0]  # 1000 > 900
    Cs, c0s, w = search_columns(C, c0, np.array([1.0]), np.array([[600.0, 1100.0]]))
    assert round_assignment(Cs, c0s, w, "weighted_sum").tolist() == [2]  # 1100 > 1000
    # two beams: another beam's pointing (NaN) is never taken even where it is worth more
    search = np.array([[50.0, np.nan], [np.nan, 1e6]])
    Cs, c0s, w = search_columns(np.array([[4000.0], [4500.0]]), c0, np.ones(1), search)
    assert Cs[0, 2] > 1e6 and Cs[1, 1] > 1e6
    assert round_assignment(Cs, c0s, w, "weighted_sum").tolist() == [0, 2]
    with pytest.raises(ValueError, match="pointing of its own"):
        search_columns(C, c0, np.ones(1), np.array([[np.nan]]))
    with pytest.raises(ValueError, match=">= 0"):
        search_columns(C, c0, np.ones(1), np.array([[-1.0]]))


def test_footprint_and_search_bearings():
    sensor = ClutteredSensor(
        RangeBearingSensor(sigma_r=10.0, sigma_b=0.01, pd=0.9, r_min=1.0, r_max=2000.0),
        beam_width=0.2,
    )
    xy = np.array([[1000.0, 0.0], [1000.0, 150.0], [0.0, 1000.0], [3000.0, 0.0]])
    pv = np.array([0.0, 10.0, 0.0, 0.0])
    # bearing 0: the first (0 rad), the second (0.149 rad > 0.1: no), the last out of range
    assert footprint(sensor, xy, pv, 0.0).tolist() == [True, False, False, False]
    assert footprint(sensor, xy, pv, math.pi / 2).tolist() == [False, False, True, False]
    with pytest.raises(ValueError, match="bearing"):
        footprint(sensor, xy, pv, None)
    # several pointings at once: one row each
    assert footprints(sensor, xy, pv, [0.0, math.pi / 2, math.pi]).tolist() == [
        [True, False, False, False],
        [False, False, True, False],
        [False] * 4,
    ]
    # cells spanning bearings 0..pi/2 as seen from the origin: ceil((pi/2) / 0.2) = 8
    # pointings one beam width apart, centred on pi/4
    b = search_bearings(xy[:3], pv, 0.2)
    assert len(b) == 8
    np.testing.assert_allclose(np.diff(b), 0.2)
    assert b.mean() == pytest.approx(math.pi / 4)
    # four cells a quarter turn apart around the sensor: the largest gap (pi / 2) is left
    # out, 3 pi / 2 in ceil(7.5 pi) = 24 pointings
    around = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0], [0.0, -1.0]])
    assert len(search_bearings(around, pv, 0.2)) == 24
    # the sensor among many cells (gaps under a beam width): all around, ceil(2 pi / 0.2)
    a = np.linspace(0.0, 2.0 * math.pi, 100, endpoint=False)
    ring = np.stack([np.cos(a), np.sin(a)], axis=-1)
    assert len(search_bearings(ring, pv, 0.2)) == 32


def _scene(surveillance: dict | None, assignment: str = "mre") -> dict:
    targets = {"objective": "gospa", "aggregate": "weighted_sum", "assignment": assignment}
    if surveillance is not None:
        targets["surveillance"] = surveillance
    return {
        "name": "search_test",
        "dt": 4.0,
        "steps": 10,
        "targets": [
            {
                "id": "t1",
                "motion": {"model": "ncv", "q": 0.5},
                "prior": {"mean": [0.0, 0.0, 5000.0, 0.0], "var": [100.0, 1.0, 100.0, 1.0]},
            },
            {
                "id": "t2",
                "motion": {"model": "ncv", "q": 0.5},
                "prior": {"mean": [0.0, 0.0, 6000.0, 0.0], "var": [1e4, 1.0, 1e4, 1.0]},
                "birth": 3,
            },
        ],
        "platforms": [
            {
                "id": "p1",
                "initial_state": [0.0, 20.0, -3000.0, 0.0],
                "sensors": [
                    {
                        "id": "radar",
                        "kind": "range_bearing",
                        "sigma_r": 10.0,
                        "sigma_b": 0.003,
                        "pd": 0.9,
                        "r_max": 16000.0,
                        "beam_width": 0.2,
                        "clutter_density": 0.0003,
                    }
                ],
            }
        ],
        "tracker": {"filter": "ekf"},
        "planner": {"horizon": 1, "targets": targets},
        "evaluation": {"cutoff": 500.0, "order": 2, "alpha": 2},
    }


SURVEILLANCE = {"region": [-5000.0, 5000.0, 0.0, 10000.0], "birth_rate": 0.5}


def test_the_surveillance_section_is_checked():
    sc = parse_scenario(_scene(SURVEILLANCE), "s")
    assert sc.planner.targets.surveillance.cell_size == 250.0
    for bad, field in (
        ({"region": [1.0, 0.0, 0.0, 1.0], "birth_rate": 0.1}, "x_min < x_max"),
        ({"region": [0.0, 1.0, 0.0], "birth_rate": 0.1}, "region"),
        ({"region": [0.0, 1.0, 0.0, 1.0], "birth_rate": -0.1}, "birth_rate"),
        ({"region": [0.0, 1e6, 0.0, 1e6], "birth_rate": 0.1, "cell_size": 1.0}, "cells"),
    ):
        with pytest.raises(ValueError, match=field):
            parse_scenario(_scene(bad), "s")
    for bad, field in (
        ({"births": "edges"}, "edges"),
        ({"births": "edges", "edges": ["north", "north"]}, "distinct edges"),
        ({"births": "edges", "edges": ["up"]}, "edges"),
        ({"births": "edges", "edges": ["west"], "birth_speed": -1.0}, "birth_speed"),
        ({"births": "along", "edges": ["west"]}, "births"),
        ({"birth_speed": 25.0}, "need births 'edges'"),
    ):
        with pytest.raises(ValueError, match=field):
            parse_scenario(_scene({**SURVEILLANCE, **bad}), "s")
    edges = {**SURVEILLANCE, "births": "edges", "edges": ["west", "east"], "birth_speed": 25.0}
    planner = build_across_targets(parse_scenario(_scene(edges), "s"), np.random.default_rng(0))
    assert planner.undetected.surveillance.edges == ("west", "east")
    assert planner.undetected.layers.shape == (2, 1600)
    # absent: the planner keeps no intensity (every other scenario's numbers stay)
    plain = build_across_targets(parse_scenario(_scene(None), "s"), np.random.default_rng(0))
    assert plain.undetected is None


def test_a_file_and_a_caller_are_told_the_same_about_a_region():
    # one set of rules (activetrack.regions): the schema's message is the planner's own
    for bad in (
        {"region": [1.0, 0.0, 0.0, 1.0]},
        {"region": [0.0, 1e6, 0.0, 1e6], "cell_size": 1.0},
        {"births": "edges"},
        {"births": "edges", "edges": ["north", "north"]},
        {"edges": ["west"]},
        {"birth_speed": 25.0},
    ):
        section = {**SURVEILLANCE, **bad}
        with pytest.raises(ValueError) as direct:
            Surveillance(
                tuple(section["region"]),
                section["birth_rate"],
                section.get("cell_size", 250.0),
                section.get("births", "uniform"),
                tuple(section.get("edges", ())),
                section.get("birth_speed", 0.0),
            )
        told = str(direct.value).replace("surveillance.", "")
        with pytest.raises(ValueError, match=re.escape(told)):
            parse_scenario(_scene(section), "s")


def _plan(planner, epoch: int, tracks: tuple, pv: np.ndarray):
    snap = [PlatformSnapshot("p1", epoch, 4.0 * epoch, pv, *heading_speed(pv))]
    return planner.plan(epoch, TrackSet(epoch, 4.0 * epoch, "ekf", tracks=tracks), snap)


def test_the_planner_searches_where_the_intensity_is_and_depletes_it():
    sc = parse_scenario(_scene(SURVEILLANCE), "s")
    planner = build_across_targets(sc, np.random.default_rng(0))
    pv = np.array(sc.platforms[0].initial_state)
    # no track: the beam searches (track -1), its look depletes the cells it saw
    d = _plan(planner, 0, (), pv)
    assert d.beams[0].track_id == -1 and d.report.search == "sweep"
    u = planner.undetected
    birth = 0.5 * 4.0 / len(u.intensity)
    np.testing.assert_allclose(u.intensity, birth)
    pv1 = pv + np.array([4.0 * pv[1], 0.0, 0.0, 0.0])
    seen = footprint(planner.sensors[0].model, u.xy, pv1, d.beams[0].bearing)
    assert 0 < seen.sum() < len(seen)
    _plan(planner, 1, (), pv1)
    np.testing.assert_allclose(u.intensity[seen], 0.2 * birth)  # (birth + birth) (1 - Pd)
    np.testing.assert_allclose(u.intensity[~seen], 2 * birth)
    # a well-held track: its service saves little, the unsearched region is worth more
    m = np.array([0.0, 0.0, 5000.0, 0.0])
    P = np.diag([25.0, 0.25, 25.0, 0.25])
    held = (TrackEstimate(1, "confirmed", m, P, m, P, existence=1.0),)
    d = _plan(planner, 2, held, pv1)
    assert d.beams[0].track_id == -1
    # the same track highly uncertain: served
    P = np.diag([4e4, 25.0, 4e4, 25.0])
    lost = (TrackEstimate(1, "confirmed", m, P, m, P, existence=1.0),)
    planner = build_across_targets(sc, np.random.default_rng(0))
    d = _plan(planner, 0, lost, pv)
    assert d.beams[0].track_id == 1


def test_random_beams_draw_among_tracks_and_search_pointings():
    sc = parse_scenario(_scene(SURVEILLANCE, assignment="random"), "s")
    planner = build_across_targets(sc, np.random.default_rng(3))
    pv = np.array(sc.platforms[0].initial_state)
    m = np.array([0.0, 0.0, 5000.0, 0.0])
    P = np.diag([25.0, 0.25, 25.0, 0.25])
    tracks = (TrackEstimate(1, "confirmed", m, P, m, P),)
    ids = [_plan(planner, k, tracks, pv).beams[0].track_id for k in range(40)]
    # 1 track and 10-11 pointings: the track about 1 in 11
    assert 0 < ids.count(1) < 12 and ids.count(-1) > 28


def test_a_tentative_track_is_a_pointing_unless_a_confirmed_one_holds_its_target():
    sc = parse_scenario(_scene(SURVEILLANCE), "s")
    planner = build_across_targets(sc, np.random.default_rng(0))
    pv = np.array(sc.platforms[0].initial_state)
    m = np.array([0.0, 0.0, 5000.0, 0.0])
    P = np.diag([25.0, 0.25, 25.0, 0.25])
    confirmed = TrackEstimate(1, "confirmed", m, P, m, P, existence=1.0)
    far = np.array([3000.0, 0.0, 5000.0, 0.0])  # 3 km off: a target of its own
    near = np.array([300.0, 0.0, 5000.0, 0.0])  # within c = 500 m of the confirmed track
    tracks = (
        confirmed,
        TrackEstimate(2, "tentative", far, P, far, P, existence=0.2),
        TrackEstimate(3, "tentative", near, P, near, P, existence=0.2),
    )
    ahead = planner._ahead(pv)
    (o,) = planner._search_options(tracks, [0], ahead[None])
    assert o.track_ids.tolist().count(-1) == len(o.track_ids) - 1
    assert o.track_ids[-1] == 2
    # its value: r Pd I c_beam c^p / alpha (the beam on its prediction: c_beam ~ 1)
    hit = planner.sensors[0].hit(far, ahead, P, NO_MISSES)
    assert hit == pytest.approx(0.9, rel=1e-3)
    assert o.values[-1] == pytest.approx(0.2 * hit * 125000.0, rel=1e-3)


def test_a_beams_search_value_from_a_position_is_its_best_pointing():
    sc = parse_scenario(_scene(SURVEILLANCE), "s")
    planner = build_across_targets(sc, np.random.default_rng(0))
    u = planner.undetected
    u.predict()
    pv = np.array(sc.platforms[0].initial_state)
    model = planner.sensors[0].model
    best = max(
        float(footprint(model, u.xy, pv, float(b)) @ u.intensity)
        for b in search_bearings(u.xy, pv, 0.2)
    )
    # Pd Lambda c^p / alpha for one epoch; birth 0.5 / s * 4 s = 2 targets over the region
    value = planner._search_value(0)
    assert value(pv) == pytest.approx(0.9 * best * 125000.0)
    assert 0.1 < best < 0.5
    inside = np.array([0.0, 20.0, 5000.0, 0.0])  # from inside the region a look sees less
    got = value(np.stack([[pv, inside], [inside, pv]]))  # candidates' axes kept
    assert got.shape == (2, 2)
    assert got[0, 0] == got[1, 1] == pytest.approx(0.9 * best * 125000.0)
    assert got[0, 1] == got[1, 0] < 0.9 * best * 125000.0


def _one_track_rollouts(value, shared: bool = False) -> dict[str, GospaRollout]:
    """mre rollouts of one leg, track 0 at 2 km (spread 1e5 m^2): "search" with the optimised
    platform's beam serving it and the search ``value``, "served" the same without search,
    "unserved" no beam on it; ``shared``: another platform's look serves it too."""
    F = np.eye(4)
    F[0, 1] = F[2, 3] = 4.0
    Q = np.diag([10.0, 1.0, 10.0, 1.0])
    x = np.array([[[0.0, 0.0, 2000.0, 0.0]]])  # (L=1, T=1, 4)
    beam = ClutteredSensor(RangeBearingSensor(sigma_r=10.0, sigma_b=0.003, pd=0.9), beam_width=0.2)
    looks = (Look(beam, np.array([shared]), np.zeros((1, 4))),)
    rest = ((NO_MISSES,), np.ones(1), W, 4.0)

    def rollout(serves: bool, search: FirstLegSearch | None = None) -> GospaRollout:
        own = ((beam, np.array([serves])),)
        return GospaRollout("mre", F, Q, x, [], looks, own, *rest, search=search)

    return {
        "search": rollout(True, FirstLegSearch((None, value), np.ones(1))),
        "served": rollout(True),
        "unserved": rollout(False),
    }


def test_the_rollout_searches_on_the_first_leg_where_that_beats_serving():
    # Candidate 0 sees no intensity (v = 0), candidate 1 a search worth 1e6 (8 targets' worth
    # of one epoch): 1 keeps the track's split without the beam's look and gains the region's
    # row -v; 0 serves the track, its region row 0.
    P1 = np.diag([5e4, 100.0, 5e4, 100.0])[None]
    pvs = np.array([[0.0, 20.0, 0.0, 0.0], [0.0, 30.0, 0.0, 0.0]])

    def value(pv):
        return np.where(np.asarray(pv)[..., 1] > 25.0, 1e6, 0.0)

    stages = _one_track_rollouts(value)
    got = stages["search"].advance(P1, 0, pvs)
    assert got.shape == (2, 2, 3)
    served = stages["served"].advance(P1, 0, pvs)
    unserved = stages["unserved"].advance(P1, 0, pvs)
    gain = float(unserved[0, 0].sum() - served[0, 0].sum())
    assert gain > 1e3  # the look is worth something
    np.testing.assert_allclose(got[0, 0], served[0, 0], rtol=1e-12)
    np.testing.assert_allclose(got[0, 1], [0.0, 0.0, 0.0])
    np.testing.assert_allclose(got[1, 0], unserved[1, 0], rtol=1e-12)
    np.testing.assert_allclose(got[1, 1], [0.0, -1e6, 0.0])
    # a search worth less than the look keeps serving; one worth just more searches
    for v, searches in ((0.99 * gain, False), (1.01 * gain, True)):
        stage = _one_track_rollouts(lambda pv, v=v: np.full(np.shape(pv)[:-1], v))["search"]
        assert stage.advance(P1, 0, pvs[:1])[0, 1, 1] == (-v if searches else 0.0)
    # shared with another platform's look: the beam keeps serving (their choice is joint)
    got = _one_track_rollouts(value, shared=True)["search"].advance(P1, 0, pvs)
    np.testing.assert_allclose(got[:, 1], 0.0)


def test_a_new_tentative_track_weighs_the_birth_odds_of_its_cell():
    # births along the north edge: a detection there is likely a target, one in the middle
    # of the region (no intensity) clutter; the tracker's fixed 0.2 gives way to e / (e + kappa)
    north = {**SURVEILLANCE, "births": "edges", "edges": ["north"], "birth_speed": 25.0}
    sc = parse_scenario(_scene(north), "s")
    planner = build_across_targets(sc, np.random.default_rng(0))
    pv = np.array(sc.platforms[0].initial_state)
    _plan(planner, 0, (), pv)
    planner.pending_looks = [(0, math.pi / 2)]  # the next look north, over both tracks
    P = np.diag([2500.0, 900.0, 2500.0, 900.0])
    edge = np.array([0.0, 0.0, 9900.0, 0.0])
    middle = np.array([0.0, 0.0, 5000.0, 0.0])
    outside = np.array([0.0, 0.0, 12000.0, 0.0])
    tracks = tuple(
        TrackEstimate(i, "tentative", m, P, m, P, hits=1, existence=0.2)
        for i, m in ((5, edge), (6, middle), (7, outside))
    )
    pv1 = planner._ahead(pv)
    _plan(planner, 1, tracks, pv1)
    u = planner.undetected
    odds = birth_odds(planner.sensors[0].model, u, pv1, np.ones(len(u.xy), dtype=bool))
    # the look depleted the cell after the odds were taken: D before = D now / (1 - Pd)
    cell = int(u.cell_of([[0.0, 9900.0]])[0])
    expect = 10.0 * odds[cell]
    assert planner._tentative_existence(tracks[0]) == pytest.approx(expect / (1.0 + expect))
    assert 0.2 < planner._tentative_existence(tracks[0]) < 1.0
    assert planner._tentative_existence(tracks[1]) == 0.0  # no births in the middle yet
    assert planner._tentative_existence(tracks[2]) == 0.0  # beyond the region
    # a later miss moves the tracker's odds, the birth factor stays with the track
    missed = replace(tracks[0], misses=1, existence=0.05)
    f = expect / 0.25
    assert planner._tentative_existence(missed) == pytest.approx(
        0.05 / 0.95 * f / (1 + 0.05 / 0.95 * f)
    )


def test_a_beams_hits_on_many_targets_are_its_hit_on_each_to_the_bit():
    """``hits`` (the tentative tracks of a search, all at once) against ``hit`` one by one:
    targets 50 m to 42 km off (r_max 16 km), wide and tight spreads."""
    sc = parse_scenario(_scene(SURVEILLANCE), "s")
    planner = build_across_targets(sc, np.random.default_rng(0))
    sensor = planner.sensors[0]
    rng = np.random.default_rng(7)
    pv = planner._ahead(np.array(sc.platforms[0].initial_state))
    xs = np.zeros((40, 4))
    xs[:, ::2] = pv[::2] + rng.uniform(-30000.0, 30000.0, (40, 2))
    xs[:, 1::2] = rng.normal(0.0, 10.0, (40, 2))
    xs[0, ::2] = pv[::2] + np.array([50.0, 0.0])
    A = rng.normal(0.0, 1.0, (40, 4, 4))
    Ps = A @ np.swapaxes(A, 1, 2) * rng.uniform(1.0, 1e4, (40, 1, 1)) + 1e-3 * np.eye(4)
    many = sensor.hits(xs, pv, Ps)
    one = [sensor.hit(x, pv, P, NO_MISSES) for x, P in zip(xs, Ps, strict=True)]
    assert many.tolist() == one
    assert 0.0 in one and max(one) > 0.5  # out of range and in the beam


def test_the_candidates_of_one_decision_share_one_search_scene():
    """The tracks' predictions, the uncovered cells and the tentative tracks are worked out
    once per decision, and again for other tracks."""
    sc = parse_scenario(_scene(SURVEILLANCE), "s")
    planner = build_across_targets(sc, np.random.default_rng(0))
    pv = np.array(sc.platforms[0].initial_state)
    m = np.array([3000.0, 0.0, 5000.0, 0.0])
    P = np.diag([25.0, 0.25, 25.0, 0.25])
    tracks = (TrackEstimate(2, "tentative", m, P, m, P, existence=0.2),)
    ahead = planner._ahead(pv)
    (first,) = planner._search_options(tracks, [0], ahead[None])
    scene = planner._search_scene
    (again,) = planner._search_options(tracks, [0], ahead[None])
    assert planner._search_scene is scene
    assert again.values.tolist() == first.values.tolist() and again.track_ids[-1] == 2
    (other,) = planner._search_options((), [0], ahead[None])
    assert planner._search_scene is not scene and -1 == other.track_ids.max()
