"""Malformed scenario files: one clear error naming the field, exit code 2, never a traceback.

A table of mutations of scenarios/default.yaml and tests/ros/data/short_two_sensors.yaml (and of
a cautious variant of the default built from it), plus raw-byte files, each run through
``activetrack batch FILE``; then every scenario file of the repository must still load.
"""

from __future__ import annotations

import copy
from pathlib import Path

import pytest
import yaml

from activetrack.limits import MAX_PLATFORMS, MAX_SENSORS
from activetrack.scenarios import ScenarioError, load_scenario, parse_scenario
from activetrack.scenarios.load import MAX_FILE_BYTES, MAX_NESTING
from activetrack_bringup.cli import main as cli_main

ROOT = Path(__file__).resolve().parents[2]
DEFAULT = ROOT / "scenarios" / "default.yaml"
SHORT = ROOT / "tests" / "ros" / "data" / "short_two_sensors.yaml"


def _base(path: Path) -> dict:
    return yaml.safe_load(path.read_text())


def _cautious_base() -> dict:
    """The default scenario turned into a one-robot beta-cautious localisation (valid)."""
    d = _base(DEFAULT)
    d["name"] = "default-cautious"
    d["target"]["motion"]["q"] = 0.0
    d["target"]["prior"] = {"mean": [0.0, 0.0, 0.0, 0.0], "var": [3600.0, 1e-6, 3600.0, 1e-6]}
    d["target"]["initial_state"] = [25.0, 0.0, -40.0, 0.0]
    d["platforms"] = [d["platforms"][0]]
    robot = d["platforms"][0]
    robot["initial_state"] = [100.0, 0.0, 0.0, 0.0]
    robot["limits"] = {"dpsi_max": 3.141592653589793, "dv_max": 1.0, "v_min": 0.0, "v_max": 1.0}
    robot["sensors"] = [{"id": "antenna", "kind": "ambiguous_bearing", "sigma": 0.26}]
    d["tracker"] = {"filter": "ekf"}
    d["planner"] = {"search": "cautious"}
    return d


BASES = {
    "default": lambda: _base(DEFAULT),
    "short": lambda: _base(SHORT),
    "cautious": _cautious_base,
}


def _set(path: str, value):
    """A mutation setting the dotted ``path`` (list indices as digits) to ``value``."""

    def apply(d):
        *head, last = path.split(".")
        node = d
        for key in head:
            node = node[int(key)] if key.isdigit() else node.setdefault(key, {})
        if last.isdigit():
            node[int(last)] = value
        else:
            node[last] = value

    return apply


def _delete(path: str):
    def apply(d):
        *head, last = path.split(".")
        node = d
        for key in head:
            node = node[int(key)] if key.isdigit() else node[key]
        del node[int(last) if last.isdigit() else last]

    return apply


def _both(*mutations):
    def apply(d):
        for m in mutations:
            m(d)

    return apply


def _many_platforms(d):
    p = d["platforms"][0]
    d["platforms"] = [
        {**copy.deepcopy(p), "id": f"p{i}", "sensors": [{**p["sensors"][0], "id": f"s{i}"}]}
        for i in range(MAX_PLATFORMS + 1)
    ]


def _many_sensors(d):
    s = d["platforms"][0]["sensors"][0]
    d["platforms"][0]["sensors"] = [{**s, "id": f"x{i}"} for i in range(MAX_SENSORS + 1)]


SENSOR = "platforms.0.sensors.0"
BEARING = f"{SENSOR}.bearing"  # pydantic adds the kind to the path
PCRLB_LIMITS = {"dpsi_max": 0.3, "dv_max": 10.0, "v_min": 50.0, "v_max": 200.0}

# (case id, base, mutation, text that must appear in the error: the field, often with the rule)
CASES = [
    # --- top level ---
    ("name-parent-dirs", "default", _set("name", "../../x"), "  name: the name"),
    ("name-absolute", "short", _set("name", "/etc/passwd"), "  name: the name"),
    ("name-hidden", "default", _set("name", ".hidden"), "  name: the name"),
    ("name-empty", "default", _set("name", ""), "  name: the name"),
    (
        "name-too-long",
        "short",
        _set("name", "n" * 101),
        "must be 1-100 characters of letters, digits",
    ),
    ("name-unicode", "default", _set("name", "szenario-ü"), "  name: the name"),
    ("name-space", "default", _set("name", "my scenario"), "  name: the name"),
    ("name-not-string", "short", _set("name", 12), "  name: Input should be a valid string"),
    ("name-missing", "default", _delete("name"), "  name: Field required"),
    (
        "dt-zero",
        "default",
        _set("dt", 0),
        "  dt: Input should be greater than or equal to 0.000001",
    ),
    ("dt-negative", "short", _set("dt", -1.0), "  dt: Input should be greater than or equal"),
    ("dt-1e300", "default", _set("dt", 1e300), "  dt: Input should be less than or equal to"),
    ("dt-text", "default", _set("dt", "soon"), "  dt: Input should be a valid number"),
    ("dt-nan", "short", _set("dt", float("nan")), "  dt: Input should be a finite number"),
    ("dt-inf", "default", _set("dt", float("inf")), "  dt: Input should be a finite number"),
    ("dt-tiny", "default", _set("dt", 1e-9), "  dt: Input should be greater than or equal"),
    ("dt-missing", "short", _delete("dt"), "  dt: Field required"),
    ("steps-zero", "default", _set("steps", 0), "  steps: Input should be greater than or equal"),
    ("steps-1e12", "default", _set("steps", 10**12), "  steps: Input should be less than or equal"),
    ("steps-fraction", "short", _set("steps", 2.5), "  steps: Input should be a valid integer"),
    ("steps-text", "default", _set("steps", "many"), "  steps: Input should be a valid integer"),
    ("steps-10**400", "default", _set("steps", 10**400), "  steps: "),
    (
        "duration-int32",
        "short",
        _both(_set("dt", 1e4), _set("steps", 1_000_000)),
        "  steps: dt * steps must be <= 1e+09 s",
    ),
    ("seed-negative", "default", _set("seed", -1), "  seed: Input should be greater than or equal"),
    ("seed-huge", "short", _set("seed", 2**64), "  seed: Input should be less than or equal"),
    ("description-huge", "default", _set("description", "d" * 20_000), "  description: "),
    ("unknown-key", "default", _set("stepz", 3), "  stepz: unknown field"),
    (
        "plugins-not-a-list",
        "short",
        _set("plugins", "my_sensors"),
        "plugins: must be a list of Python module names, got str 'my_sensors'",
    ),
    ("plugins-path", "default", _set("plugins", ["../x.py"]), "plugins[0]: must be a Python modu"),
    ("plugins-relative", "short", _set("plugins", ["json", ".x"]), "plugins[1]: must be a Python"),
    ("plugins-keyword", "default", _set("plugins", ["my.class"]), "plugins[0]: must be a Python"),
    (
        "plugins-not-importable",
        "short",
        _set("plugins", ["json", "no_such_activetrack_plugin.sensors"]),
        "plugins[1]: cannot import module 'no_such_activetrack_plugin.sensors' "
        "(ModuleNotFoundError: No module named 'no_such_activetrack_plugin'); it must be "
        "importable in every process",
    ),
    ("top-level-typo-nested", "short", _set("tracker.particels", 10), "  tracker.particels:"),
    # --- target ---
    ("motion-unknown", "default", _set("target.motion.model", "sonar"), "  target.motion: must be"),
    ("motion-q-negative", "default", _set("target.motion.q", -1.0), "  target.motion.ncv.q:"),
    ("motion-q-1e300", "short", _set("target.motion.q", 1e300), "  target.motion.ncv.q:"),
    (
        "motion-sigma-missing",
        "default",
        _set("target.motion", {"model": "ncv_discrete", "sigma_x": 5.0}),
        "  target.motion.ncv_discrete.sigma_y: Field required",
    ),
    (
        "motion-omega-huge",
        "default",
        _set("target.motion", {"model": "constant_turn", "omega": 1e9, "q": 0.0}),
        "  target.motion.constant_turn.omega: Input should be less than or equal",
    ),
    (
        "prior-mean-1e300",
        "default",
        _set("target.prior.mean", [1e300, -40.0, 1000.0, -40.0]),
        "  target.prior.mean: entry 0 (x) must be within +-1e+09",
    ),
    (
        "prior-mean-short",
        "short",
        _set("target.prior.mean", [1000.0, -40.0, 1000.0]),
        "  target.prior.var: must have 3 entries",
    ),
    (
        "prior-var-zero",
        "default",
        _set("target.prior.var", [0.0, 0.0, 0.0, 0.0]),
        "  target.prior.var: the covariance must be symmetric positive definite",
    ),
    (
        "prior-var-negative",
        "short",
        _set("target.prior.var", [-1.0, 1.0, 1.0, 1.0]),
        "  target.prior.var.0: Input should be greater than or equal to 0",
    ),
    (
        "prior-var-1e19",
        "short",
        _set("target.prior.var", [1e19, 1.0, 10.0, 1.0]),
        "  target.prior.var.0: Input should be less than or equal to 1000000000000000000",
    ),
    (
        "prior-var-tiny",
        "default",
        _set("target.prior.var", [1e-20, 1.0, 10.0, 1.0]),
        "  target.prior.var: the covariance's smallest eigenvalue must be >= 1e-12",
    ),
    (
        "prior-var-and-cov",
        "default",
        _set("target.prior.cov", [[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 1.0, 0], [0, 0, 0, 1.0]]),
        "  target.prior: give exactly one of cov",
    ),
    (
        "prior-cov-asymmetric",
        "short",
        _both(
            _delete("target.prior.var"),
            _set("target.prior.cov", [[1, 0.5, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]),
        ),
        "  target.prior.cov: the covariance must be symmetric",
    ),
    (
        "prior-cov-ragged",
        "default",
        _both(_delete("target.prior.var"), _set("target.prior.cov", [[1, 0], [0, 1, 0], [1]])),
        "  target.prior.cov: must be 4x4 to match mean",
    ),
    (
        "target-initial-state-long",
        "default",
        _set("target.initial_state", [1.0, 2.0, 3.0, 4.0, 5.0]),
        "  target.initial_state: must have 4 entries",
    ),
    (
        "target-initial-state-far",
        "short",
        _set("target.initial_state", [0.0, 1e300, 0.0, 0.0]),
        "  target.initial_state: entry 1 (xdot) must be within +-1e+06",
    ),
    (
        "target-circular-with-planner",
        "default",
        _set(
            "target",
            {
                "motion": {"model": "circular", "sigma_omega": 1e-4, "sigma_v": 1e-3},
                "prior": {"mean": [0, 1000, 1000, 0.01, 50], "var": [0.01, 10, 10, 1e-6, 1]},
            },
        ),
        "  target.motion.model: planning and sensor selection need linear pv dynamics",
    ),
    # --- platforms and sensors ---
    ("platforms-empty", "default", _set("platforms", []), "  platforms: List should have at least"),
    ("platforms-too-many", "short", _many_platforms, "  platforms: List should have at most 100"),
    ("platform-id-slash", "default", _set("platforms.0.id", "a/b"), "  platforms.0.id: a platform"),
    ("platform-id-duplicate", "short", _set("platforms.1.id", "p1"), "platform ids must be unique"),
    (
        "platform-state-short",
        "default",
        _set("platforms.0.initial_state", [1.0, 2.0, 3.0]),
        "  platforms.0.initial_state: List should have at least 4 items",
    ),
    (
        "platform-speed-1e300",
        "short",
        _set("platforms.0.initial_state", [1800.0, 1e300, 2000.0, -40.0]),
        "  platforms.0.initial_state: entry 1 (xdot) must be within +-1e+06",
    ),
    (
        "platform-state-text",
        "default",
        _set("platforms.0.initial_state", ["a", 0, 0, 0]),
        "  platforms.0.initial_state.0: Input should be a valid number",
    ),
    (
        "platform-at-rest-pcrlb",
        "default",
        _set("platforms.0.initial_state", [1800.0, 0.0, 2000.0, 0.0]),
        "  platforms.0.initial_state: a platform steered by PCRLB planning needs a nonzero",
    ),
    (
        "platform-on-target",
        "short",
        _both(
            _set("platforms.0.initial_state", [1000.0, -40.0, 1000.0, -40.0]),
            _set("platforms.0.sensors.0.r_min", 0.0),
        ),
        "  platforms.0.initial_state: the platform starts on the target's position",
    ),
    (
        "controllable-without-limits",
        "default",
        _delete("platforms.0.limits"),
        "  platforms.0.limits: a controllable platform needs limits",
    ),
    (
        "limits-both-pairs",
        "short",
        _set("platforms.0.limits", {**PCRLB_LIMITS, "a_max": 1.0, "psi_rate_max": 0.1}),
        "  platforms.0.limits: give exactly one of the pairs",
    ),
    (
        "limits-dpsi-beyond-pi",
        "default",
        _set("platforms.0.limits.dpsi_max", 10.0),
        "  platforms.0.limits.dpsi_max: Input should be less than or equal to 3.14",
    ),
    (
        "limits-vmin-above-vmax",
        "short",
        _set("platforms.0.limits.v_min", 300.0),
        "  platforms.0.limits.v_min: must not exceed v_max",
    ),
    (
        "limits-vmax-1e300",
        "default",
        _set("platforms.0.limits.v_max", 1e300),
        "  platforms.0.limits.v_max: Input should be less than or equal to 1000000",
    ),
    (
        "limits-vmin-zero-pcrlb",
        "default",
        _set("platforms.0.limits.v_min", 0.0),
        "  platforms.0.limits.v_min: must be > 0 for a platform steered by PCRLB planning",
    ),
    (
        "limits-a-max-1e300",
        "short",
        _set("platforms.0.limits", {"a_max": 1e300, "psi_rate_max": 0.1, "v_max": 200.0}),
        "  platforms.0.limits.a_max: Input should be less than or equal",
    ),
    ("sensors-empty", "default", _set("platforms.0.sensors", []), "  platforms.0.sensors: List"),
    ("sensors-too-many", "short", _many_sensors, "  platforms.0.sensors: List should have at most"),
    (
        "sensor-kind-unknown",
        "default",
        _set("platforms.0.sensors.0.kind", "sonar"),
        "  platforms.0.sensors.0: must be one of",
    ),
    ("sensor-sigma-zero", "default", _set(f"{SENSOR}.sigma", 0.0), f"  {BEARING}.sigma:"),
    ("sensor-sigma-tiny", "short", _set(f"{SENSOR}.sigma", 1e-300), f"  {BEARING}.sigma:"),
    ("sensor-sigma-huge", "default", _set(f"{SENSOR}.sigma", 100.0), f"  {BEARING}.sigma:"),
    ("sensor-sigma-missing", "short", _delete(f"{SENSOR}.sigma"), f"  {BEARING}.sigma:"),
    ("sensor-pd-zero", "default", _set(f"{SENSOR}.pd", 0.0), f"  {BEARING}.pd:"),
    ("sensor-pd-above-one", "short", _set(f"{SENSOR}.pd", 1.5), f"  {BEARING}.pd:"),
    ("sensor-rmin-negative", "default", _set(f"{SENSOR}.r_min", -1.0), f"  {BEARING}.r_min:"),
    (
        "sensor-rmax-below-rmin",
        "short",
        _set(f"{SENSOR}.r_max", 10.0),
        f"  {BEARING}.r_max: must be greater than r_min",
    ),
    ("sensor-rmax-1e300", "default", _set(f"{SENSOR}.r_max", 1e300), f"  {BEARING}.r_max:"),
    ("sensor-id-duplicate", "short", _set("platforms.1.sensors.0.id", "s1"), "sensor ids must be"),
    ("sensor-id-empty", "default", _set(f"{SENSOR}.id", ""), f"  {BEARING}.id: a sensor id"),
    # --- tracker ---
    ("tracker-filter-unknown", "default", _set("tracker.filter", "ukf"), "  tracker.filter: must"),
    ("tracker-particles-zero", "short", _set("tracker.particles", 0), "  tracker.particles: Input"),
    ("tracker-particles-1e7", "default", _set("tracker.particles", 10**7), "  tracker.particles:"),
    (
        "tracker-particles-too-few-to-plan",
        "short",
        _set("tracker.particles", 50),
        "  tracker.particles: must be >= 100 with filter 'pf' when the planner works",
    ),
    ("planner-samples-1e6", "short", _set("tracker.planner_samples", 10**6), "planner_samples:"),
    ("ess-threshold-zero", "default", _set("tracker.ess_threshold", 0.0), "  tracker.ess_thresh"),
    ("roughening-1e300", "default", _set("tracker.roughening", 1e300), "  tracker.roughening:"),
    (
        "tracker-motion-other-state",
        "short",
        _set("tracker.motion", {"model": "circular", "sigma_omega": 1e-4, "sigma_v": 1e-3}),
        "  tracker.motion.model: must estimate the target's state",
    ),
    # --- planner ---
    (
        "horizon-zero",
        "default",
        _set("planner.horizon", 0),
        "  planner.horizon: must be an integer in [1, 10]",
    ),
    (
        "horizon-eleven",
        "short",
        _set("planner.horizon", 11),
        "  planner.horizon: must be an integer in [1, 10]",
    ),
    (
        "horizon-bool",
        "short",
        _set("planner.horizon", True),
        "  planner.horizon: must be an integer in [1, 10]",
    ),
    (
        "horizon-text",
        "short",
        _set("planner.horizon", "three"),
        "  planner.horizon: must be an integer in [1, 10]",
    ),
    (
        "horizon-fraction",
        "short",
        _set("planner.horizon", 2.5),
        "  planner.horizon: must be an integer in [1, 10]",
    ),
    (
        "horizon-exponential",
        "default",
        _set("planner.horizon", 5),
        "  planner.horizon: search 'quadrant' with horizon 5 costs 34^5",
    ),
    ("search-unknown", "default", _set("planner.search", "astar"), "  planner.search: must be"),
    ("grid-size-1e6", "short", _set("planner.grid_size", 10**6), "  planner.grid_size: Input"),
    (
        "grid-two-step",
        "default",
        _both(_set("planner.search", "grid"), _set("planner.horizon", 2)),
        "  planner.horizon: search 'grid' with horizon 2 costs 10201^2",
    ),
    ("divisions-1000", "default", _set("planner.quadrant_divisions", 1000), "quadrant_divisions:"),
    ("patience-zero", "short", _set("planner.quadrant_patience", 0), "quadrant_patience:"),
    ("sector-levels-100", "default", _set("planner.sector_levels", 100), "  planner.sector_levels"),
    ("mc-samples-1e6", "short", _set("planner.mc_samples", 10**6), "  planner.mc_samples: Input"),
    (
        "mc-samples-grid-memory",
        "default",
        _both(
            _set("tracker", {"filter": "ekf"}),
            _set("planner.search", "grid"),
            _set("planner.mc_samples", 100_000),
        ),
        "  planner.mc_samples: 100000 samples x 2048 candidates",
    ),
    ("sensor-iterations-0", "short", _set("planner.max_sensor_iterations", 0), "max_sensor_iter"),
    (
        "pcrlb-criterion-heading",
        "default",
        _set("planner.criterion", "heading"),
        "  planner.criterion: must be one of ('b_k', 'trace', 'trace_pos', 'det_pos') with cost "
        "'pcrlb'",
    ),
    (
        "mre-with-evolution",
        "short",
        _both(_set("planner.cost", "mre"), _set("planner.search", "evolution")),
        "  planner.search: must be one of ('sector', 'quadrant', 'grid') with cost 'mre'",
    ),
    (
        "mre-two-step-too-large",
        "default",
        _both(
            _set("planner.cost", "mre"),
            _both(_set("planner.search", "grid"), _set("planner.horizon", 2)),
        ),
        "  planner.horizon: search 'grid' with cost 'mre' and horizon 2 costs 10201^2",
    ),
    ("cost-unknown", "short", _set("planner.cost", "entropy"), "  planner.cost: must be one of"),
    (
        "selection-count-above-sensors",
        "default",
        _set("planner.selection", {"enabled": True, "count": 3}),
        "  planner.selection.count: must be <= 2 (the number of sensors), got 3",
    ),
    (
        "selection-fixed-unknown-sensor",
        "short",
        _set("planner.selection", {"enabled": True, "strategy": "fixed", "fixed_sensor": "s9"}),
        "  planner.selection.fixed_sensor: must be one of ['s1', 's2']",
    ),
    (
        "selection-fixed-count-two",
        "default",
        _set(
            "planner.selection",
            {"enabled": True, "strategy": "fixed", "fixed_sensor": "s1", "count": 2},
        ),
        "  planner.selection.count: must be 1 with strategy 'fixed'",
    ),
    (
        "selection-strategy-unknown",
        "short",
        _set("planner.selection", {"enabled": True, "strategy": "best"}),
        "  planner.selection.strategy: must be one of",
    ),
    (
        "selection-heading-still-target",
        "default",
        _both(
            _set("target.prior.mean", [1000.0, 0.0, 1000.0, 0.0]),
            _set("planner.selection", {"enabled": True, "criterion": "heading"}),
        ),
        "  planner.selection.criterion: 'heading' needs a moving target",
    ),
    (
        "selection-range-target-at-origin",
        "short",
        _both(
            _set("target.prior.mean", [0.0, 0.0, 0.0, 0.0]),
            _set("planner.selection", {"enabled": True, "criterion": "range"}),
        ),
        "  planner.selection.criterion: 'range' is taken from the origin",
    ),
    # --- the cautious planner (Vander Hook) ---
    (
        "cautious-two-robots",
        "default",
        _set("planner", {"search": "cautious"}),
        "  planner.search: 'cautious' needs exactly one controllable platform (the robot), got 2",
    ),
    (
        "cautious-range-sensor",
        "cautious",
        _set(
            "platforms.0.sensors.0",
            {"id": "a", "kind": "range_bearing", "sigma_r": 1.0, "sigma_b": 0.1},
        ),
        "  platforms.0.sensors: search 'cautious' needs exactly one sensor of kind",
    ),
    (
        "cautious-sensor-too-noisy",
        "cautious",
        _set("platforms.0.sensors.0.sigma", 1.2),
        "  platforms.0.sensors.0.sigma: must be < sigma_beta(beta=0.1, two_sided)",
    ),
    (
        "cautious-one-sided-beta",
        "cautious",
        _set("planner.cautious", {"beta": 0.6, "tail": "one_sided"}),
        "  planner.cautious.beta: must be in (0, 0.5] with tail 'one_sided', got 0.6",
    ),
    (
        "cautious-infinite-sigma-beta",
        "cautious",
        _set("planner.cautious", {"beta": 0.5, "tail": "one_sided", "r_min": 0.0}),
        "  planner.cautious.r_min: must be > 0 when sigma_beta is infinite",
    ),
    (
        "cautious-selection",
        "cautious",
        _set("planner.selection", {"enabled": True}),
        "  planner.selection.enabled: sensor selection is not available with search 'cautious'",
    ),
    (
        "cautious-two-step",
        "cautious",
        _set("planner.horizon", 2),
        "  planner.horizon: must be 1 with search 'cautious'",
    ),
    (
        "cautious-open-loop",
        "cautious",
        _set("planner.mode", "open_loop"),
        "  planner.mode: must be 'renewal' with search 'cautious'",
    ),
    (
        "cautious-mre",
        "cautious",
        _set("planner.cost", "mre"),
        "  planner.cost: must be left at 'pcrlb' with search 'cautious'",
    ),
    ("cautious-dwell-1e300", "cautious", _set("planner.cautious.t_m", 1e300), "cautious.t_m:"),
    (
        "cautious-beta-one",
        "cautious",
        _set("planner.cautious.beta", 1.0),
        "  planner.cautious.beta: Input should be less than 1",
    ),
]


def _run_batch(path, capsys) -> tuple[int, str, str]:
    rc = cli_main(["batch", str(path)])
    out, err = capsys.readouterr()
    return rc, out, err


def _assert_one_error(rc: int, out: str, err: str, path, expected: str) -> None:
    assert rc == 2
    assert out == ""  # nothing ran
    assert "Traceback" not in err
    assert err.startswith(f"error: {path}: ")
    assert [line for line in err.splitlines() if "error:" in line] == [err.splitlines()[0]]
    assert expected in err, err


def test_the_cautious_base_is_valid():
    parse_scenario(_cautious_base())


def test_the_table_has_at_least_80_cases_with_unique_ids():
    ids = [c[0] for c in CASES] + [c[0] for c in RAW_CASES]
    assert len(ids) >= 80
    assert len(set(ids)) == len(ids)


@pytest.mark.parametrize(("case", "base", "mutate", "expected"), CASES, ids=[c[0] for c in CASES])
def test_malformed_scenario_is_one_clear_error(case, base, mutate, expected, tmp_path, capsys):
    data = BASES[base]()
    parse_scenario(copy.deepcopy(data))  # the base itself is valid: the mutation is the fault
    mutate(data)
    path = tmp_path / f"{case}.yaml"
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    rc, out, err = _run_batch(path, capsys)
    _assert_one_error(rc, out, err, path, expected)


def _bomb(levels: int = 9) -> bytes:
    lines = ['a0: &a0 ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    for i in range(1, levels + 1):
        lines.append(f"a{i}: &a{i} [" + ", ".join([f"*a{i - 1}"] * 9) + "]")
    return ("\n".join(lines) + "\n").encode()


_VALID = DEFAULT.read_bytes()
RAW_CASES = [
    ("raw-latin1", _VALID.replace(b"two bearings-only", b"zwei Sensorpl\xe4tze"), "not a UTF-8"),
    ("raw-binary", bytes(range(256)) * 4, "not a UTF-8 text file (byte 0x80 at offset 128)"),
    ("raw-nul-bytes", b"name: x\x00y\ndt: 1\n", "not valid YAML"),
    ("raw-png-header", b"\x89PNG\r\n\x1a\n" + bytes(64), "not a UTF-8"),
    ("raw-deep-flow", b"[" * 100_000 + b"]" * 100_000, f"nested deeper than {MAX_NESTING}"),
    ("raw-deep-block", "".join(f"{' ' * i}k:\n" for i in range(200)).encode(), "nested deeper"),
    ("raw-billion-laughs", _bomb(), "aliases are expanded (an alias bomb?)"),
    ("raw-recursive-alias", b"&a [*a]\n", "alias *a refers to itself"),
    ("raw-unknown-alias", b"name: *nowhere\n", "alias *nowhere refers to itself or to no anchor"),
    ("raw-too-large", b"# " + b"x" * MAX_FILE_BYTES + b"\n", "too large for a scenario file"),
    ("raw-empty", b"", "the file is empty"),
    ("raw-whitespace", b"  \n\n\t\n", "the file is empty"),
    ("raw-comment-only", b"# nothing here\n", "the file holds no scenario (only comments)"),
    ("raw-list", b"- name: x\n- dt: 1\n", "a scenario must be a mapping of fields"),
    ("raw-scalar", b"42\n", "a scenario must be a mapping of fields (name:, dt:, ...), got int"),
    ("raw-string", b"just some words\n", "a scenario must be a mapping"),
    ("raw-two-documents", _VALID + b"---\nname: y\n", "not valid YAML"),
    ("raw-tab-indent", b"name: x\ntarget:\n\tmotion: 1\n", "not valid YAML at line 3"),
    ("raw-python-tag", b"name: !!python/object/apply:os.system ['true']\n", "not valid YAML"),
    ("raw-unhashable-key", b"? [a, b]\n: 1\n", "not valid YAML"),
    ("raw-unclosed-quote", b'name: "x\ndt: 1\n', "not valid YAML"),
    ("raw-utf16", _VALID.decode().encode("utf-16"), "not a UTF-8"),
]


@pytest.mark.parametrize(("case", "content", "expected"), RAW_CASES, ids=[c[0] for c in RAW_CASES])
def test_raw_file_is_one_clear_error(case, content, expected, tmp_path, capsys):
    path = tmp_path / f"{case}.yaml"
    path.write_bytes(content)
    rc, out, err = _run_batch(path, capsys)
    _assert_one_error(rc, out, err, path, expected)
    assert len(err.strip().splitlines()) == 1, err  # a file-level reason fits on one line


@pytest.mark.parametrize(
    ("case", "expected"),
    [("directory", "is a directory"), ("missing", "cannot read scenario file: No such file")],
)
def test_unusable_path_is_one_clear_error(case, expected, tmp_path, capsys):
    path = tmp_path / "dir" if case == "directory" else tmp_path / "nope.yaml"
    if case == "directory":
        path.mkdir()
    rc, out, err = _run_batch(path, capsys)
    _assert_one_error(rc, out, err, path, expected)


def test_path_with_nul_character_is_a_scenario_error():
    with pytest.raises(ScenarioError, match="cannot read scenario file"):
        load_scenario("bad\x00name.yaml")


def test_every_violated_cross_field_rule_is_listed(tmp_path):
    data = _base(DEFAULT)
    data["planner"]["criterion"] = "heading"
    data["tracker"]["particles"] = 10
    data["planner"]["selection"] = {"enabled": True, "count": 5}
    path = tmp_path / "three.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ScenarioError) as info:
        load_scenario(path)
    lines = str(info.value).splitlines()
    assert lines[0] == f"{path}: invalid scenario"
    fields = sorted(line.split(":")[0].strip() for line in lines[1:])
    assert fields == ["planner.criterion", "planner.selection.count", "tracker.particles"]


def test_long_error_lists_are_cut(tmp_path):
    data = _base(DEFAULT)
    data.update({f"typo{i}": i for i in range(50)})
    path = tmp_path / "typos.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(ScenarioError, match=r"\.\.\. and 30 more$"):
        load_scenario(path)


def test_anchors_and_aliases_of_a_normal_size_still_work(tmp_path):
    text = DEFAULT.read_text().replace(
        "    limits: {dpsi_max: 0.3141592653589793, dv_max: 10.0, v_min: 50.0, v_max: 200.0}",
        "    limits: &lim {dpsi_max: 0.3141592653589793, dv_max: 10.0, v_min: 50.0, v_max: 200.0}",
        1,
    )
    text = text.replace(
        "    limits: {dpsi_max: 0.3141592653589793, dv_max: 10.0, v_min: 50.0, v_max: 200.0}",
        "    limits: *lim",
    )
    assert "*lim" in text and "&lim" in text
    path = tmp_path / "aliases.yaml"
    path.write_text(text)
    assert load_scenario(path) == load_scenario(DEFAULT)


SCENARIO_FILES = sorted((ROOT / "scenarios").glob("*.yaml")) + sorted(
    (ROOT / "tests").rglob("*.yaml")
)


@pytest.mark.parametrize("path", SCENARIO_FILES, ids=[p.name for p in SCENARIO_FILES])
def test_every_scenario_of_the_repository_still_loads(path):
    assert load_scenario(path).name == path.stem
