"""The rules of a scenario file that ask the registries and the components.

The schema (:mod:`.schema`) checks the file's shape; these rules run after it, in the loader
(:func:`activetrack.scenarios.load.parse_scenario`), one layer above the components they ask:
the filter and criterion registries for the names a file gives, the planner's criteria, searches
and cautious strategy, and the sensors (built from their entries) for what they measure and
whether clutter is modelled for them. Every rule is one the cores would otherwise break on when
built or in their first epochs, so a scenario that loads runs. Each violation is a
``(field, message)`` pair; the loader prints one ``field: message`` line each.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from activetrack import limits
from activetrack.arraytypes import ArrayLike
from activetrack.filters.registry import filter_kind, filter_names, make_filter
from activetrack.models.base import as_linear
from activetrack.models.clutter import fov_volume, has_clutter_model, starts_tracks
from activetrack.planning.cautious import caution_gamma, sigma_beta
from activetrack.planning.criteria import PCRLB, POSITIONING, criterion_names, get_criterion
from activetrack.planning.selection import POSITIONING_SEARCHES
from activetrack.scenarios.build import build_motion_model, build_sensor
from activetrack.scenarios.fields import MOTION_STATE, PV_MODELS, position_of, shown
from activetrack.scenarios.registry import registered_kinds, sensor_kind
from activetrack.scenarios.schema import (
    CautiousConfig,
    MotionConfig,
    PlannerConfig,
    PlatformConfig,
    Scenario,
    TrackerConfig,
)
from activetrack.scenarios.tracking import TrackingConfig, TrackingPlatformConfig

__all__ = ["name_problems", "scenario_problems", "tracking_problems"]

Problems = list[tuple[str, str]]


def _one_of(names: tuple[str, ...]) -> str:
    """``'a', 'b' or 'c'``: the allowed values as pydantic lists a Literal's."""
    shown = [repr(n) for n in names]
    return shown[0] if len(shown) == 1 else f"{', '.join(shown[:-1])} or {shown[-1]}"


# --- names the registries hold -----------------------------------------------------------------


def _filter_problem(value: str) -> str | None:
    names = filter_names()
    if value in names:
        return None
    return f"must be one of {_one_of(names)}, got {shown(value, 40)}"


def _criterion_problem(value: str, *uses: str) -> str | None:
    """A planner criterion that applies to one of ``uses`` (the registry,
    activetrack.planning.criteria, decides: a registered criterion is accepted at once)."""
    names = criterion_names(*uses)
    return None if value in names else f"must be one of {_one_of(names)}"


# The fields whose allowed values a registry holds, and the check of each.
_NAMED_FIELDS = (
    (("tracker", "filter"), _filter_problem),
    (("planner", "criterion"), lambda v: _criterion_problem(v, "pcrlb", "positioning")),
    (("planner", "selection", "criterion"), lambda v: _criterion_problem(v, "selection")),
)


def name_problems(data: object) -> Problems:
    """The filter and criterion names a scenario's data (the parsed file) gives that are not
    registered. Read from the data, not a validated scenario, so that the loader reports them
    with the schema's errors too; entries that are absent (the defaults, built-in names) or
    not text (the schema's error) are left alone."""
    out = []
    for path, check in _NAMED_FIELDS:
        node: Any = data
        for key in path:
            node = node.get(key) if isinstance(node, Mapping) else None
        problem = check(node) if isinstance(node, str) else None
        if problem is not None:
            out.append((".".join(path), problem))
    return out


# --- across sections ---------------------------------------------------------------------------


def _problem(text: str) -> Problems:
    """``"field: message"`` as the one problem ``[(field, message)]``."""
    field, message = text.split(": ", 1)
    return [(field, message)]


def _violated(*rules: tuple[bool, str]) -> Problems:
    """``(field, message)`` of each rule ``(violated, "field: message")`` that is violated."""
    return [problem for violated, text in rules if violated for problem in _problem(text)]


def scenario_problems(s: Scenario) -> Problems:
    """``(field, message)`` for every violated rule across sections (empty: none) of a
    scenario the schema validated and whose names (:func:`name_problems`) are registered."""
    duration = s.dt * s.steps
    out = _violated(
        (
            duration > limits.MAX_DURATION,
            f"steps: dt * steps must be <= {limits.MAX_DURATION:g} s (ROS stamps hold int32 "
            f"seconds), got {s.dt:g} * {s.steps} = {duration:.3g} s",
        )
    )
    # The filters start from the targets' priors, so they must estimate the same state.
    tracker_model = (s.tracker.motion or s.target.motion).model
    for i, t in enumerate(s.targets):
        layout = MOTION_STATE[t.motion.model]
        same = [m for m, names in MOTION_STATE.items() if names == layout]
        field = "tracker.motion.model" if i == 0 else f"targets.{i}.motion.model"
        out += _violated(
            (
                MOTION_STATE[tracker_model] != layout,
                f"{field}: must estimate the target's state {layout} (the prior is given in it): "
                f"one of {same} for targets.{i}.motion.model {t.motion.model!r}, got "
                f"{tracker_model!r}",
            )
        )
    # Range 0 at epoch 0: bearings (and their Jacobians in the EKF and the MRE) are undefined.
    for n, t in enumerate(s.targets):
        starts = [(f"targets.{n}.prior.mean", t.prior.mean)]
        if t.initial_state is not None:
            starts.append((f"targets.{n}.initial_state", t.initial_state))
        for i, p in enumerate(s.platforms):
            blind = [sensor.id for sensor in p.sensors if sensor.r_min == 0.0]
            here = (p.initial_state[0], p.initial_state[2])
            for label, state in starts:
                out += _violated(
                    (
                        bool(blind) and position_of(state, t.motion.model) == here,
                        f"platforms.{i}.initial_state: the platform starts on the target's "
                        f"position ({label}), where bearings are undefined (range 0): move it, or "
                        f"give its sensors {blind} an r_min > 0",
                    )
                )
    out += _scene_problems(s)
    if s.planner.enabled:
        out += _planner_problems(s)
    return out


def _planner_problems(s: Scenario) -> Problems:
    cfg = s.planner
    sel = cfg.selection
    robots = [(i, p) for i, p in enumerate(s.platforms) if p.controllable]
    if cfg.search == "cautious":
        out = _cautious_problems(s, robots)
        uses_track = True
    else:
        out = _steering_problems(s, robots)
        uses_track = (bool(robots) or sel.enabled) and cfg.mode == "renewal"
    if sel.enabled:
        out += _selection_problems(s)
    # Criteria of the MRE (e.g. Ramdaras eq. 25-26) evaluated at the predicted target state.
    criteria = []
    if sel.enabled and cfg.search != "cautious":
        criteria.append(("planner.selection.criterion", sel.criterion))
    if cfg.cost == "mre" and robots and cfg.search != "cautious":
        criteria.append(("planner.criterion", cfg.criterion))
    if criteria and s.target.motion.model in PV_MODELS:
        out += _criterion_problems(s, criteria)
    particles = filter_kind(s.tracker.filter).particle_based  # the particle rules apply
    return out + _violated(
        (
            uses_track and particles and s.tracker.particles < limits.MIN_PARTICLES_FOR_PLANNING,
            f"tracker.particles: must be >= {limits.MIN_PARTICLES_FOR_PLANNING} with filter "
            f"{s.tracker.filter!r} when the planner works from the track (its covariance must "
            f"stay invertible), got {s.tracker.particles}",
        )
    )


def _steering_problems(s: Scenario, robots: list[tuple[int, PlatformConfig]]) -> Problems:
    """PCRLB planning or MRE positioning of the controllable platforms (not cautious)."""
    cfg = s.planner
    target_model = s.target.motion.model
    mre = cfg.cost == "mre"
    positioning = criterion_names(POSITIONING)
    out = _violated(
        (
            mre and cfg.search not in POSITIONING_SEARCHES,
            f"planner.search: must be one of {POSITIONING_SEARCHES} with cost 'mre', got "
            f"{cfg.search!r}",
        ),
        (
            mre and bool(robots) and cfg.criterion not in positioning,
            f"planner.criterion: must be one of {positioning} with cost 'mre', got "
            f"{cfg.criterion!r}",
        ),
    )
    if mre and cfg.horizon != 1 and cfg.search in POSITIONING_SEARCHES:
        # Multi-step positioning nests one search per leg (planning.selection.plan_positions):
        # per_stage^R evaluations, per_call^R candidate covariances (4 x 4) scored together.
        per_stage, per_call = _search_size(cfg)
        R = cfg.horizon
        out += _violated(
            (
                per_stage**R > limits.MAX_SEARCH_EVALUATIONS
                or 16 * per_call**R > limits.MAX_PLANNER_BATCH,
                f"planner.horizon: search {cfg.search!r} with cost 'mre' and horizon {R} costs "
                f"{per_stage}^{R} = {float(per_stage**R):.3g} cost evaluations per platform and "
                f"decision, {per_call}^{R} covariances scored together; at most "
                f"{limits.MAX_SEARCH_EVALUATIONS:.0e} and {limits.MAX_PLANNER_BATCH // 16:.3g} "
                "(activetrack.limits): lower the horizon or the search's size",
            )
        )
    out += _violated(
        (
            (bool(robots) or cfg.selection.enabled) and target_model not in PV_MODELS,
            "target.motion.model: planning and sensor selection need linear pv dynamics, one of "
            f"{PV_MODELS}, got {target_model!r} (or set planner.enabled: false)",
        )
    )
    if robots and cfg.cost == "pcrlb":
        out += _pcrlb_problems(s, robots, criterion_names(PCRLB))
    return out


def _selection_problems(s: Scenario) -> Problems:
    """Sensor selection (Ramdaras eq. 27) among the scenario's sensors."""
    sel = s.planner.selection
    sensor_ids = [sensor.id for p in s.platforms for sensor in p.sensors]
    fixed = sel.strategy == "fixed"
    return _violated(
        (
            sel.count > len(sensor_ids),
            f"planner.selection.count: must be <= {len(sensor_ids)} (the number of sensors), got "
            f"{sel.count}",
        ),
        (
            fixed and sel.fixed_sensor not in sensor_ids,
            f"planner.selection.fixed_sensor: must be one of {sensor_ids} with strategy 'fixed', "
            f"got {sel.fixed_sensor!r}",
        ),
        (
            fixed and sel.count != 1,
            f"planner.selection.count: must be 1 with strategy 'fixed', got {sel.count}",
        ),
    )


def _cautious_problems(s: Scenario, robots: list[tuple[int, PlatformConfig]]) -> Problems:
    """Vander Hook's beta-cautious planner (closed_loop.cautious, planning.cautious)."""
    cfg = s.planner
    c = cfg.cautious
    model = s.target.motion.model
    out = _violated(
        (
            len(robots) != 1,
            f"planner.search: 'cautious' needs exactly one controllable platform (the robot), got "
            f"{len(robots)}: {[p.id for _, p in robots]}",
        ),
        (
            cfg.cost != "pcrlb",
            "planner.cost: must be left at 'pcrlb' with search 'cautious', got 'mre'",
        ),
        (
            cfg.horizon != 1,
            "planner.horizon: must be 1 with search 'cautious' (Algorithm 1 is greedy), got "
            f"{cfg.horizon}",
        ),
        (
            cfg.mode != "renewal",
            "planner.mode: must be 'renewal' with search 'cautious' (it plans from the track), "
            f"got {cfg.mode!r}",
        ),
        (
            cfg.selection.enabled,
            "planner.selection.enabled: sensor selection is not available with search 'cautious'",
        ),
        (
            model not in PV_MODELS,
            f"target.motion.model: search 'cautious' needs a pv motion model, one of {PV_MODELS}, "
            f"got {model!r}",
        ),
    )
    if c.tail == "one_sided" and c.beta > 0.5:
        return out + _problem(
            f"planner.cautious.beta: must be in (0, 0.5] with tail 'one_sided', got {c.beta}"
        )
    if len(robots) == 1:
        out += _cautious_robot_problems(c, *robots[0])
    return out


def _cautious_robot_problems(c: CautiousConfig, i: int, robot: PlatformConfig) -> Problems:
    """The robot's one bearing sensor and the beta-cautious strategy's existence for it."""
    sensors = [build_sensor(cfg) for cfg in robot.sensors]
    if len(sensors) != 1 or tuple(sensors[0].components) != ("bearing",):
        kinds = [cfg.kind for cfg in robot.sensors]
        bearing_only = tuple(  # the registered kinds that measure one bearing
            kind
            for kind in registered_kinds()
            if tuple(getattr(sensor_kind(kind).sensor_class, "components", ())) == ("bearing",)
        )
        return _problem(
            f"platforms.{i}.sensors: search 'cautious' needs exactly one sensor of kind "
            f"{bearing_only} on the robot, got {kinds}"
        )
    # The bearing's standard deviation (sqrt of R: exactly sigma for the built-in kinds).
    sigma = math.sqrt(float(np.atleast_2d(np.asarray(sensors[0].R, dtype=float))[0, 0]))
    sb = sigma_beta(c.beta, c.tail)
    if not sb > sigma:
        return _problem(
            f"platforms.{i}.sensors.0.sigma: must be < sigma_beta(beta={c.beta}, {c.tail}) = "
            f"{sb:.6g} rad for a beta-cautious strategy to exist (Vander Hook sec. III), got "
            f"{sigma}"
        )
    return _violated(
        (
            math.isinf(caution_gamma(c.beta, sigma, c.tail)) and c.r_min <= 0.0,
            "planner.cautious.r_min: must be > 0 when sigma_beta is infinite (tail 'one_sided', "
            "beta 0.5)",
        )
    )


def _pcrlb_problems(
    s: Scenario, robots: list[tuple[int, PlatformConfig]], criteria: tuple[str, ...]
) -> Problems:
    """PCRLB manoeuvre planning (planning.planner, planning.horizons)."""
    cfg = s.planner
    out = _violated(
        (
            cfg.criterion not in criteria,
            f"planner.criterion: must be one of {criteria} with cost 'pcrlb', got "
            f"{cfg.criterion!r}",
        )
    )
    for i, p in robots:
        v_min = p.limits.v_min if p.limits is not None else 0.0  # limits: given when controllable
        out += _violated(
            (
                math.hypot(p.initial_state[1], p.initial_state[3]) == 0.0,
                f"platforms.{i}.initial_state: a platform steered by PCRLB planning needs a "
                "nonzero initial velocity (its heading)",
            ),
            (
                v_min <= 0.0,
                f"platforms.{i}.limits.v_min: must be > 0 for a platform steered by PCRLB "
                f"planning (at rest it would have no heading), got {v_min}",
            ),
        )
    R = cfg.horizon
    if cfg.search == "evolution":
        batch = _EVOLUTION_POPSIZE * 2 * R
    else:
        per_stage, per_call = _search_size(cfg)
        if per_stage**R > limits.MAX_SEARCH_EVALUATIONS:
            return out + _problem(
                f"planner.horizon: search {cfg.search!r} with horizon {R} costs "
                f"{per_stage}^{R} = {float(per_stage**R):.3g} cost evaluations per platform "
                f"and decision; at most {limits.MAX_SEARCH_EVALUATIONS:.0e} "
                "(activetrack.limits): lower the horizon or the search's size"
            )
        batch = per_call**R
    pf_renewal = filter_kind(s.tracker.filter).particle_based and cfg.mode == "renewal"
    samples = min(s.tracker.planner_samples, s.tracker.particles) if pf_renewal else cfg.mc_samples
    field = "tracker.planner_samples" if pf_renewal else "planner.mc_samples"
    return out + _violated(
        (
            batch * samples > limits.MAX_PLANNER_BATCH,
            f"{field}: {samples} samples x {batch} candidates scored together (search "
            f"{cfg.search!r}, horizon {R}) exceeds {limits.MAX_PLANNER_BATCH:.1e} (about 1 GB, "
            f"activetrack.limits): use at most {limits.MAX_PLANNER_BATCH // batch} samples",
        )
    )


def _criterion_problems(s: Scenario, criteria: Problems) -> Problems:
    """Criteria undefined at the predicted target state (the registry's ``state_problem``:
    heading of a target at rest; range, Doppler and bearing taken from the origin, Ramdaras
    eq. 26, with the target there). Checked at the first prediction."""
    F = as_linear(build_motion_model(s.target.motion)).transition_matrix(s.dt)
    x = F @ np.asarray(s.target.prior.mean, dtype=float)
    out = []
    for field, name in criteria:
        problem = get_criterion(name).state_problem
        reason = problem(x) if problem is not None else None
        if reason:
            out.append((field, f"{name!r} {reason} (target.prior.mean)"))
    return out


# Per-stage candidates of the searches (activetrack.planning.searches) for the size rules.
_GRID_CHUNK = 2048  # grid_search scores at most this many points per problem and call
_EVOLUTION_POPSIZE = 15  # SearchSettings.evolution_popsize (scipy: popsize x dimensions)


def _search_size(cfg: PlannerConfig) -> tuple[int, int]:
    """(cost evaluations of one search stage, candidates scored per call) for a DP search."""
    if cfg.search == "grid":
        return cfg.grid_size**2, min(cfg.grid_size**2, _GRID_CHUNK)
    if cfg.search == "quadrant":
        return 9 + 5 * (cfg.quadrant_divisions - 1), 9
    return 16 + 12 * (cfg.sector_levels - 1) + 1, 16  # sector


# --- multi-target scenarios (a targets: list) --------------------------------------------------


def _sensor_problems(platforms: Sequence[PlatformConfig | TrackingPlatformConfig]) -> Problems:
    """Clutter and fields of view: only for the sensors that model them (asked of the sensor,
    activetrack.models.clutter), bounded per scan."""
    out: Problems = []
    for i, p in enumerate(platforms):
        for j, cfg in enumerate(p.sensors):
            where = f"platforms.{i}.sensors.{j}"
            if cfg.fov_width is not None and cfg.beam_width is not None:
                out.append((f"{where}.beam_width", "give fov_width or beam_width, not both"))
            if cfg.clutter_density > 0:
                out += _clutter_problems(where, cfg)
    return out


def _clutter_problems(where: str, cfg: Any) -> Problems:
    sensor = build_sensor(cfg)
    if not has_clutter_model(sensor):
        return _problem(
            f"{where}.clutter_density: sensor kind {cfg.kind!r} has no clutter model (its "
            "clutter_volume is None; docs/extending.md): keep clutter_density 0"
        )
    width = cfg.beam_width or cfg.fov_width or 2.0 * math.pi
    volume = fov_volume(sensor, width, cfg.r_min, cfg.r_max)
    mean = cfg.clutter_density * volume
    return _violated(
        (
            not math.isfinite(volume),
            f"{where}.r_max: must be finite for a range-bearing sensor with clutter (the clutter "
            "is uniform over [r_min, r_max])",
        ),
        (
            math.isfinite(volume) and mean > limits.MAX_CLUTTER_PER_SCAN,
            f"{where}.clutter_density: the mean false alarms per scan (density x field of view "
            f"{mean:.3g}) must be <= {limits.MAX_CLUTTER_PER_SCAN:g}",
        ),
    )


def _filter_associates(
    tracker: TrackerConfig, motion: MotionConfig, mean: ArrayLike, cov: ArrayLike
) -> bool:
    """Whether the tracker's filter has an ``update_pda`` (the JPDA's update): one is built
    from N(mean, cov) to ask it (the registry's factory, a throwaway generator)."""
    model = build_motion_model(motion)
    x0, P0 = np.array(mean, dtype=float), np.array(cov, dtype=float)
    built = make_filter(tracker.filter, model, x0, P0, tracker, np.random.default_rng(0))
    return callable(getattr(built, "update_pda", None))


_NO_UPDATE_PDA = (
    "must be a filter that takes associated detections (an update_pda, as the built-in 'ekf' "
    "and 'pf' have; docs/extending.md)"
)


def _starts_tracks(platforms: Sequence[PlatformConfig | TrackingPlatformConfig]) -> bool:
    """Whether a sensor fixes a position from one detection (it starts tracks)."""
    return any(starts_tracks(build_sensor(c)) for p in platforms for c in p.sensors)


def _scene_problems(s: Scenario) -> Problems:
    """``(field, message)`` for every violated rule of the scene: the targets' lifetimes, the
    sensors' clutter and fields of view, and what associating detections (JPDA: several
    targets, births and deaths, or clutter) asks of the targets, the filter and the planner."""
    out = _sensor_problems(s.platforms)
    ids = [t.id for t in s.targets]
    dupes = sorted({v for v in ids if ids.count(v) > 1})
    out += _violated((bool(dupes), f"targets: target ids must be unique, repeated: {dupes}"))
    for i, t in enumerate(s.targets):
        out += _violated(
            (t.birth >= s.steps, f"targets.{i}.birth: must be < steps ({s.steps}), got {t.birth}"),
            (
                t.death is not None and t.death <= t.birth,
                f"targets.{i}.death: must be > birth ({t.birth}), got {t.death}",
            ),
        )
    beams = any(c.beam_width is not None for p in s.platforms for c in p.sensors)
    cfg = s.planner
    one_target_planning = cfg.enabled and (cfg.search == "cautious" or cfg.selection.enabled)
    out += _violated(
        (
            cfg.targets.pointing == "footprint" and cfg.targets.objective != "criterion",
            "planner.targets.pointing: 'footprint' centres beams on planner.criterion; with "
            "objective 'gospa' beams point at their tracks: use pointing 'track'",
        ),
        (
            cfg.targets.pointing == "footprint" and cfg.targets.aggregate != "weighted_sum",
            "planner.targets.pointing: 'footprint' centres beams on the tracks' weighted sum; "
            "use aggregate 'weighted_sum' (or pointing 'track' for the worst track's)",
        ),
        (
            cfg.targets.clutter_gate == "innovation" and cfg.cost != "mre",
            "planner.targets.clutter_gate: 'innovation' sets the information reduction of the "
            "MRE's expected update (cost 'mre'); the PCRLB's J_Z keeps q of R: use cost 'mre' "
            "or clutter_gate 'measurement'",
        ),
    )
    if s.known_association:
        return out + _violated(
            (
                beams and one_target_planning,
                "planner: steerable beams are pointed by planning across tracks; search "
                "'cautious' and planner.selection plan for one target without beams",
            ),
            (
                not beams and cfg.targets.objective != "criterion",
                "planner.targets.objective: 'gospa' plans across tracks (several targets, "
                "clutter, births and deaths, or steerable beams); one target known to be the "
                "only one is planned on planner.criterion: use 'criterion'",
            ),
        )
    why = "when detections are associated (several targets, births and deaths, or clutter)"
    for i, t in enumerate(s.targets):
        out += _violated(
            (
                t.motion.model not in ("ncv", "ncv_discrete"),
                f"targets.{i}.motion.model: must be an NCV pv model ('ncv', 'ncv_discrete') "
                f"{why}, got {t.motion.model!r}",
            )
        )
    first = s.targets[0]
    motion = s.tracker.motion or first.motion
    associates = _filter_associates(s.tracker, motion, first.prior.mean, first.prior.covariance())
    return out + _violated(
        (
            any(t.birth > 0 for t in s.targets) and not _starts_tracks(s.platforms),
            "targets: a target born after epoch 0 needs a sensor that fixes a position from one "
            "detection (e.g. range_bearing) to start its track (bearings-only tracks start from "
            "the priors of the targets present at epoch 0)",
        ),
        (not associates, f"tracker.filter: {_NO_UPDATE_PDA} {why}, got {s.tracker.filter!r}"),
        (
            one_target_planning,
            "planner: search 'cautious' and planner.selection plan for one target whose "
            "detections are known to be its own (no clutter, no births or deaths)",
        ),
        (cfg.enabled and cfg.mode != "renewal", f"planner.mode: must be 'renewal' {why}"),
    )


# --- tracker-only configurations ---------------------------------------------------------------


def tracking_problems(c: TrackingConfig) -> Problems:
    """``(field, message)`` for every violated rule of a tracker configuration the schema
    validated (:mod:`.tracking`) and whose names (:func:`name_problems`) are registered: the
    sensors' clutter and fields of view, and what its association asks of the targets, the
    sensors, the motion model and the filter."""
    out = _sensor_problems(c.platforms)
    clutter = [s.id for p in c.platforms for s in p.sensors if s.clutter_density > 0]
    motion = c.tracker.motion
    assert motion is not None  # the schema's rule
    if c.association == "known":
        return out + _violated(
            (
                len(c.targets) != 1,
                "targets: association 'known' tracks exactly one target (every detection is its "
                f"own): give one target, got {len(c.targets)}",
            ),
            (
                bool(clutter),
                f"association: must not be 'known' with sensors in clutter {clutter} (a detection "
                "may be a false alarm): use 'jpda' or 'auto'",
            ),
        )
    if c.known_association:  # auto: one target, no clutter
        return out
    why = "when detections are associated (association 'jpda')"
    if MOTION_STATE[motion.model] != MOTION_STATE["ncv"]:
        return out + _problem(
            f"tracker.motion.model: must be a model of the pv state {MOTION_STATE['ncv']}, "
            f"one of {PV_MODELS}, {why} (tracks from detections start in it), got "
            f"{motion.model!r}"
        )
    n = len(MOTION_STATE[motion.model])
    mean, cov = np.zeros(n), np.eye(n)
    if c.targets:
        mean, cov = np.array(c.targets[0].prior.mean), c.targets[0].prior.covariance()
    associates = _filter_associates(c.tracker, motion, mean, cov)
    return out + _violated(
        (
            not c.targets and not _starts_tracks(c.platforms),
            "targets: without targets every track starts from detections: this needs a sensor "
            "that fixes a position from one detection (e.g. range_bearing); give the targets' "
            "priors for bearings-only sensors",
        ),
        (not associates, f"tracker.filter: {_NO_UPDATE_PDA} {why}, got {c.tracker.filter!r}"),
    )
