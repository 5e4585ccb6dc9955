"""The multi-target loop: scenario rules, the simulator's detections and clutter, the closed loop's
determinism, the batch command.

Scenarios: scenarios/mt_*.yaml, shortened where a run's length does not matter.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from activetrack.closed_loop.batch import run_batch
from activetrack.closed_loop.components import build_simulator, scene_targets
from activetrack.closed_loop.loop import run_once
from activetrack.data import BeamCommand, Command
from activetrack.scenarios import ScenarioError, load_scenario, parse_scenario
from activetrack.scenarios.schema import Scenario
from activetrack_bringup.cli import main as cli_main

ROOT = Path(__file__).resolve().parents[2]
CROSSING = ROOT / "scenarios" / "mt_bearings_crossing.yaml"
APPEAR = ROOT / "scenarios" / "mt_appear_disappear.yaml"


def _short(path: Path, steps: int, **planner) -> Scenario:
    data = yaml.safe_load(path.read_text())
    data["steps"] = steps
    for t in data["targets"]:
        t["birth"] = min(t.get("birth", 0), steps - 1)
        if t.get("death") is not None:
            t["death"] = max(t["birth"] + 1, min(t["death"], steps))
    data["planner"].update(planner)
    return Scenario.model_validate(data)


# --- scenario rules ---------------------------------------------------------------------------


def _crossing(**change) -> dict:
    data = yaml.safe_load(CROSSING.read_text())
    for dotted, value in change.items():
        node = data
        *path, last = dotted.split("/")
        for key in path:
            node = node[int(key)] if key.isdigit() else node[key]
        node[last] = value
    return data


RULES = [
    ({"targets/0/birth": 40}, "targets.0.birth: must be < steps (40), got 40"),
    ({"targets/1/birth": 5, "targets/1/death": 5}, "targets.1.death: must be > birth (5)"),
    (
        {"platforms/0/sensors/0/fov_width": 1.0},
        "platforms.0.sensors.0.beam_width: give fov_width or beam_width, not both",
    ),
    ({"targets/1/birth": 3}, "a target born after epoch 0 needs a sensor that fixes a position"),
    ({"tracker/filter": "ukf"}, "tracker.filter"),
    ({"planner/mode": "open_loop"}, "planner.mode: must be 'renewal' when detections are"),
    ({"platforms/0/sensors/0/clutter_density": -1.0}, "clutter_density"),
    ({"platforms/0/sensors/0/clutter_density": 1e5}, "mean false alarms per scan"),
    ({"targets/2/id": "t1"}, "target ids must be unique, repeated: ['t1']"),
    ({"targets/0/motion": {"model": "ncv", "q": 0.01, "x": 1}}, "targets.0.motion"),
]


@pytest.mark.parametrize(("change", "expected"), RULES)
def test_a_broken_multitarget_rule_is_one_clear_error(change, expected):
    with pytest.raises(ScenarioError, match=None) as info:
        parse_scenario(_crossing(**change), "mt.yaml")
    assert expected in str(info.value)


def test_one_target_in_clutter_is_associated_like_many():
    """One target is the simplest scene: with clutter its detections are associated (JPDA and
    track management), and its planner must then renew like a multi-target one."""
    data = yaml.safe_load((ROOT / "scenarios" / "default.yaml").read_text())
    assert parse_scenario(data, "default.yaml").known_association
    data["platforms"][0]["sensors"][0]["clutter_density"] = 1.0
    assert not parse_scenario(data, "default.yaml").known_association
    data["planner"]["mode"] = "open_loop"
    with pytest.raises(ScenarioError, match="planner.mode: must be 'renewal' when detections"):
        parse_scenario(data, "default.yaml")


def test_an_unbounded_range_bearing_sensor_cannot_have_clutter():
    data = yaml.safe_load(APPEAR.read_text())
    data["platforms"][0]["sensors"][0]["r_max"] = math.inf
    with pytest.raises(ScenarioError, match=r"sensors\.0\.r_max: must be finite"):
        parse_scenario(data, "mt.yaml")


def test_the_first_target_stands_as_target():
    s = load_scenario(CROSSING)
    assert len(scene_targets(s)) == 3 and s.target == s.targets[0]
    again = Scenario.model_validate(s.model_dump())  # dumped with both: accepted
    assert again == s


# --- the simulator ---------------------------------------------------------------------------


def test_scans_hold_pd_detections_and_poisson_clutter():
    """Surveillance radar of mt_appear_disappear (all around, pd 0.8, lambda V = 1.50 per
    scan): detections per scan average pd * (targets in view) + lambda V."""
    s = _short(APPEAR, 60, enabled=False)
    sim = build_simulator(s, np.random.default_rng(3))
    radar = sim.sensors["surv1"][1]
    lam_v = radar.clutter_density * 2 * math.pi * (12000.0 - 100.0)
    assert lam_v == pytest.approx(1.4954, abs=1e-4)
    counts, expected, clutter = [], [], []
    while not sim.finished:
        scans = {sc.sensor_id: sc for sc in sim.advance()}
        labels = {t.sensor_id: t.labels for t in sim.last_truth}
        j = list(sim.sensors).index("surv1")
        counts.append(len(scans["surv1"].Z))
        expected.append(0.8 * sim.last_observed[j].sum() + lam_v)
        clutter.append(sum(1 for label in labels["surv1"] if label == ""))
    n = len(counts)
    assert np.mean(clutter) == pytest.approx(lam_v, abs=4 * math.sqrt(lam_v / n))
    sd = math.sqrt(np.mean(expected) / n)
    assert np.mean(counts) == pytest.approx(np.mean(expected), abs=4 * sd)


def test_detections_are_unlabelled_and_targets_live_between_birth_and_death():
    s = _short(APPEAR, 60, enabled=False)
    record = run_once(s, 0)
    alive = ~np.isnan(record.truth[:, :, 0])
    for n, t in enumerate(s.targets):
        death = t.death if t.death is not None else s.steps + 1
        want = (np.arange(s.steps + 1) >= t.birth) & (np.arange(s.steps + 1) < death)
        np.testing.assert_array_equal(alive[:, n], want)
    # The order of a scan's detections says nothing about their origin: clutter first as often
    # as a target first.
    firsts = [
        st.labels[0] == "" for epoch in record.scan_truth for st in epoch if len(st.labels) > 1
    ]
    assert 0.2 < np.mean(firsts) < 0.8
    assert record.observed.shape == (s.steps, 3, 4)


def test_a_beam_command_is_checked():
    s = load_scenario(CROSSING)
    sim = build_simulator(s, np.random.default_rng(0))
    with pytest.raises(ValueError, match="sensor_id must be a steerable sensor"):
        sim.apply_beam(BeamCommand("nope", 0, 0.0))
    with pytest.raises(ValueError, match="epoch must be the current epoch 0, got 1"):
        sim.apply_beam(BeamCommand("s1", 1, 0.0))
    with pytest.raises(ValueError, match="bearing must be finite"):
        sim.apply_beam(BeamCommand("s1", 0, math.nan))
    sim.apply_beam(BeamCommand("s1", 0, 7.0))
    assert sim.pointing["s1"] == pytest.approx(7.0 - 2 * math.pi)
    assert sim.apply_command(Command("p1", 0, 1.0, 0.0)).clamped  # limits as one target


# --- the closed loop -------------------------------------------------------------------------


def test_a_run_is_a_function_of_seed_and_run_only():
    s = _short(CROSSING, 12)
    a, b, c = run_once(s, 3), run_once(s, 3), run_once(s, 4)
    np.testing.assert_array_equal(a.truth, b.truth)
    np.testing.assert_array_equal(a.platform_paths, b.platform_paths)
    for ta, tb in zip(a.tracks, b.tracks, strict=True):
        assert [t.track_id for t in ta.tracks] == [t.track_id for t in tb.tracks]
        for x, y in zip(ta.tracks, tb.tracks, strict=True):
            np.testing.assert_array_equal(x.mean, y.mean)
            np.testing.assert_array_equal(x.cov, y.cov)
    assert not np.allclose(a.truth[1:], c.truth[1:])


def test_a_batch_summary_holds_gospa_and_a_row_per_target_and_epoch():
    # (one process or two: test_api.test_results_do_not_depend_on_jobs)
    s = _short(CROSSING, 10)
    one = run_batch(s, runs=3, jobs=1)
    assert len(one.run_gospa) == 3 and one.mean_gospa == pytest.approx(np.mean(one.run_gospa))
    # The tables hold one row per target and epoch (per run: and run), as for one target.
    N, K = 3, s.steps
    assert one.rmse_t.shape == one.bound_t.shape == (N, K, 2)
    rows = one.table()
    assert len(rows) == N * K and [r["target"] for r in rows[::K]] == ["t1", "t2", "t3"]
    np.testing.assert_array_equal([r["rmse_x_m"] for r in rows], one.rmse_t[..., 0].ravel())
    assert len(one.run_table()) == 3 * N * K


def test_batch_prints_gospa_for_a_multitarget_scenario(tmp_path, capsys):
    s = _short(CROSSING, 8)
    path = tmp_path / "mt.yaml"
    path.write_text(yaml.safe_dump(s.model_dump(mode="json")))
    out_json = tmp_path / "s.json"
    assert cli_main(["batch", str(path), "--runs", "2", "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "3 target(s)" in out and "GOSPA" in out and "\n  t3 " in out
    import json

    data = json.loads(out_json.read_text())
    assert len(data["run_gospa"]) == 2 and data["target_ids"] == ["t1", "t2", "t3"]


def test_batch_json_is_strict_with_null_where_a_target_is_absent(tmp_path):
    """t2 is born at epoch 3 of 6: its error and bound before then are null (as in run's
    summary.json), and the file parses with NaN refused."""
    s = _short(APPEAR, 6)
    data = s.model_dump(mode="json")
    data["targets"][1]["birth"] = 3
    path = tmp_path / "appear.yaml"
    path.write_text(yaml.safe_dump(data))
    out = tmp_path / "s.json"
    assert cli_main(["batch", str(path), "--runs", "1", "--json", str(out)]) == 0

    def refuse(name):
        raise ValueError(f"non-strict JSON constant {name}")

    summary = json.loads(out.read_text(), parse_constant=refuse)
    t2 = summary["target_ids"].index("t2")
    assert summary["rmse_x_t"][t2][:2] == [None, None]
    assert summary["bound_y_t"][t2][:2] == [None, None]
    assert all(isinstance(v, float) for v in summary["rmse_x_t"][t2][3:])
