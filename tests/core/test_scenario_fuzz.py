"""Seeded fuzzing of scenario loading (hypothesis, derandomized, few examples).

1. Mutated bytes of real scenario files: ``load_scenario`` returns a Scenario or raises
   ScenarioError, never anything else, and never through its last-resort "internal check" path.
2. Mutated fields of real scenarios: whatever loads builds the simulator, tracker and planner
   and survives the first closed-loop epoch (the load-time rules are complete).
"""

from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from activetrack.closed_loop.components import build_planner, build_simulator, build_tracker
from activetrack.closed_loop.loop import apply_decision
from activetrack.scenarios import Scenario, ScenarioError, load_scenario, parse_scenario

ROOT = Path(__file__).resolve().parents[2]
FILES = [
    ROOT / "scenarios" / "default.yaml",
    ROOT / "tests" / "ros" / "data" / "short_two_sensors.yaml",
    ROOT / "scenarios" / "ramdaras_case3_pd.yaml",
    ROOT / "scenarios" / "valverde_circular.yaml",
    ROOT / "scenarios" / "vanderhook_cautious.yaml",
]
TEXTS = [f.read_bytes() for f in FILES]
FUZZ = settings(
    derandomize=True,
    database=None,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

# Lines that break scenarios in the ways the robustness audit found.
NASTY_LINES = [
    b"dt: 1e300",
    b"steps: 1000000000000",
    b"steps: 1e12",
    b"name: ../../x",
    b"seed: -1",
    b"tracker: {filter: pf, particles: 100000000}",
    b"planner: {horizon: 10, search: grid, grid_size: 1001}",
    b"planner: {search: cautious}",
    b"planner: {cost: mre, search: evolution}",
    b"target: {motion: {model: circular, sigma_omega: 1, sigma_v: 1}}",
    b"&a [*a]",
    b"[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[",
    b"- - - - - - -",
    b"? [a, b]",
    b"  : :",
    b"\t- x",
    b"\x00\xff\xfe",
    b"!!python/object:os.system x",
    b"*undefined",
    b"---",
    b"name: !!binary aGVsbG8=",
    b"dt: .nan",
    b"dt: .inf",
    b"var: [1.0e-320, 1, 1, 1]",
]


@st.composite
def mutated_file(draw) -> bytes:
    data = bytearray(draw(st.sampled_from(TEXTS)))
    for _ in range(draw(st.integers(1, 4))):
        op = draw(st.sampled_from(["insert", "delete", "flip", "line", "truncate"]))
        i = draw(st.integers(0, len(data)))
        if op == "insert":
            data[i:i] = draw(st.binary(min_size=1, max_size=8))
        elif op == "delete":
            del data[i : i + draw(st.integers(1, 40))]
        elif op == "flip" and i < len(data):
            data[i] = draw(st.integers(0, 255))
        elif op == "line":
            lines = bytes(data).split(b"\n")
            k = draw(st.integers(0, len(lines) - 1))
            lines[k] = draw(st.sampled_from(NASTY_LINES))
            data = bytearray(b"\n".join(lines))
        else:
            del data[i:]
    return bytes(data)


@settings(FUZZ, max_examples=300)
@given(content=mutated_file())
def test_load_scenario_raises_only_scenario_error(content, tmp_path_factory):
    path = tmp_path_factory.mktemp("fuzz", numbered=True) / "mutated.yaml"
    path.write_bytes(content)
    try:
        scenario = load_scenario(path)
    except ScenarioError as exc:
        message = str(exc)
        assert message.startswith(f"{path}: ")
        assert "internal check failed" not in message, message
        assert "Traceback" not in message
    else:
        assert isinstance(scenario, Scenario)


# --- field mutations that load must run --------------------------------------------------------

BASES = [yaml.safe_load(f.read_text()) for f in FILES]
BEARING = {"id": "s1", "kind": "bearing", "sigma": 0.01}
PCRLB_LIMITS = {"dpsi_max": 0.314, "dv_max": 10.0, "v_min": 50.0, "v_max": 200.0}
# (dotted path, candidate values): valid, borderline and invalid values of each field.
FIELDS = {
    "dt": [5.0, 1.0, 0.5, 1e-6, 0.0, -1.0, 1e300, "x"],
    "steps": [1, 2, 30, 0, 10**12, 2.5],
    "seed": [0, 7, -1, 2**70],
    "name": ["fuzz-ok.1", "../x", "", ".a"],
    "target.motion": [
        {"model": "ncv", "q": 1e-8},
        {"model": "ncv", "q": 0.0},
        {"model": "ncv_discrete", "sigma_x": 5.0, "sigma_y": 5.0},
        {"model": "constant_turn", "omega": 0.05, "q": 1e-4},
        {"model": "constant_turn", "omega": 0.0, "q": 1.0},
        {"model": "circular", "sigma_omega": 1e-4, "sigma_v": 1e-3},
        {"model": "circular_known_omega", "omega": 0.05, "sigma_v": 1e-3},
        {"model": "ncv", "q": 1e300},
    ],
    "target.prior.mean": [
        [1000.0, -40.0, 1000.0, -40.0],
        [0.0, 0.0, 0.0, 0.0],
        [1800.0, -40.0, 2000.0, -40.0],
        [0.0, 30.0, -20.0, 0.05, 1.0],
        [1.0, 2.0, 3.0],
    ],
    "target.prior.var": [[10.0, 1.0, 10.0, 1.0], [1e-6] * 4, [0.0] * 4, [1.0] * 5, [1e8] * 4],
    "target.initial_state": [None, [1000.0, -40.0, 1000.0, -40.0], [0.0, 0.0, 0.0, 0.0]],
    "platforms.0.initial_state": [
        [1800.0, -40.0, 2000.0, -40.0],
        [1000.0, -40.0, 1000.0, -40.0],
        [0.0, 0.0, 0.0, 0.0],
        [1800.0, 0.0, 2000.0, 0.0],
    ],
    "platforms.0.controllable": [True, False],
    "platforms.0.limits": [
        None,
        PCRLB_LIMITS,
        {"dpsi_max": 3.14159, "dv_max": 1.0, "v_min": 0.0, "v_max": 1.0},
        {"a_max": 10.0, "psi_rate_max": 0.157, "v_min": 50.0, "v_max": 200.0},
    ],
    "platforms.0.sensors": [
        [{**BEARING, "r_min": 1000.0}],
        [BEARING],
        [{"id": "s1", "kind": "ambiguous_bearing", "sigma": 0.26}],
        [{"id": "s1", "kind": "range_bearing", "sigma_r": 30.0, "sigma_b": 0.002}],
        [{"id": "s1", "kind": "range_rate_bearing", "sigma_r": 8, "sigma_rr": 10, "sigma_b": 0.02}],
        [{**BEARING, "pd": 0.5, "r_max": 5000.0}],
        [BEARING, {"id": "s1b", "kind": "bearing", "sigma": 0.05}],
    ],
    "tracker": [
        {"filter": "pf", "particles": 200},
        {"filter": "ekf"},
        {"filter": "pf", "particles": 50},
        {"filter": "pf", "particles": 150, "resample": "ess", "roughening": 0.2},
        {"filter": "pf", "particles": 150, "min_range": "negative"},
        {"filter": "ekf", "motion": {"model": "circular", "sigma_omega": 1e-4, "sigma_v": 1e-3}},
        {"filter": "ekf", "motion": {"model": "constant_turn", "omega": 0.01, "q": 1e-6}},
    ],
    "planner.enabled": [True, False],
    "planner.cost": ["pcrlb", "mre"],
    "planner.criterion": ["b_k", "trace", "det_pos", "heading", "range", "doppler", "bearing"],
    "planner.horizon": [1, 2, 3, 0],
    "planner.search": ["grid", "quadrant", "sector", "cautious"],
    "planner.grid_size": [3, 11, 101, 2],
    "planner.mode": ["renewal", "open_loop"],
    "planner.selection": [
        {"enabled": False},
        {"enabled": True},
        {"enabled": True, "strategy": "random", "count": 2},
        {"enabled": True, "strategy": "fixed", "fixed_sensor": "s1"},
        {"enabled": True, "strategy": "trace", "criterion": "heading"},
        {"enabled": True, "criterion": "doppler", "count": 5},
    ],
    "planner.cautious": [{}, {"beta": 0.5, "tail": "one_sided", "r_min": 0.0}, {"beta": 0.01}],
    "planner.sector_levels": [1, 3, 5],
    "planner.quadrant_divisions": [1, 6, 50],
}
MUTATIONS = [(path, value) for path, values in FIELDS.items() for value in values]


def _apply(data: dict, path: str, value) -> None:
    *head, last = path.split(".")
    node = data
    for key in head:
        if key.isdigit():
            node = node[int(key)]
        else:
            if node.get(key) is None:
                node[key] = {}
            node = node[key]
    if value is None:
        node.pop(last, None)
    else:
        node[last] = copy.deepcopy(value)


def _cheap(scenario: Scenario) -> Scenario:
    """The same scenario with few planner samples and particles (the time budget)."""
    data = scenario.model_dump()
    data["planner"]["mc_samples"] = min(data["planner"]["mc_samples"], 50)
    data["tracker"]["planner_samples"] = min(data["tracker"]["planner_samples"], 50)
    data["tracker"]["particles"] = min(data["tracker"]["particles"], 2000)
    return parse_scenario(data, "cheap")


def _first_epoch(scenario: Scenario) -> None:
    """Build the three components and run epoch 0 -> 1 as the batch loop does (run_once)."""
    sim = build_simulator(scenario, np.random.default_rng(0))
    tracker = build_tracker(scenario, np.random.default_rng(0))
    planner = build_planner(scenario, np.random.default_rng(0))
    decision = planner.decide(0, tracker.snapshot(), sim.platform_snapshots())
    apply_decision(sim, decision)
    scans = sim.advance()
    tracks = tracker.step(1, sim.time, scans)
    if not sim.finished:
        planner.decide(1, tracks, sim.platform_snapshots())


@settings(FUZZ, max_examples=150)
@given(
    base=st.sampled_from(range(len(BASES))),
    mutations=st.lists(st.sampled_from(MUTATIONS), min_size=2, max_size=4),
)
def test_every_scenario_that_loads_runs_its_first_epoch(base, mutations):
    data = copy.deepcopy(BASES[base])
    for path, value in mutations:
        _apply(data, path, value)
    try:
        scenario = parse_scenario(data)
    except ScenarioError as exc:
        assert "internal check failed" not in str(exc), str(exc)
        return
    _first_epoch(_cheap(scenario))


def test_every_single_field_mutation_that_loads_runs_its_first_epoch():
    """All (base, field value) pairs, not a sample: each is rejected at load or runs."""
    ran, failures = 0, []
    for base in BASES:
        for path, value in MUTATIONS:
            data = copy.deepcopy(base)
            _apply(data, path, value)
            try:
                scenario = parse_scenario(data, base["name"])
            except ScenarioError as exc:
                assert "internal check failed" not in str(exc), str(exc)
                continue
            try:
                _first_epoch(_cheap(scenario))
            except Exception as exc:
                failures.append(f"{base['name']} {path}={value!r}: {type(exc).__name__}: {exc}")
            ran += 1
    assert failures == []
    assert ran >= 300  # most single changes are valid: the sweep exercises the cores
