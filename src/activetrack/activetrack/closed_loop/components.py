"""The closed loop's components built from a validated scenario: the simulator, the tracker
and the planner, each drawing from its own generator (:func:`component_rngs`). The components
take built objects, never the scenario; these builders are where a scenario file becomes them.
The tracker is built from a tracker configuration (:mod:`activetrack.scenarios.tracking`): a
scenario's, or one written for recorded detections (docs/track-your-data.md).

The planner (:func:`build_planner`) runs the strategies the scenario's ``planner`` section
asks for (:class:`activetrack.planning.decision.Planner`), in order:

- a scene of several targets, births and deaths, clutter or steerable beams: planning across
  targets (:class:`~activetrack.planning.across_targets.MultiTargetPlanner`: manoeuvres
  against every confirmed track, beams assigned to tracks; ``enabled: false`` holds course and
  still points the beams);
- ``enabled: false``: HoldCourse;
- ``search: cautious``: CautiousLocalisation (Vander Hook et al.);
- ``cost: pcrlb`` without selection: PcrlbPlanning (Hernandez);
- ``cost: mre`` and/or ``selection.enabled`` (Ramdaras): MrePrediction, then for the
  controllable platforms PcrlbPlanning (``cost: pcrlb``) or MrePositioning (``cost: mre``),
  then the selection strategy of ``selection.strategy`` (``SELECTION_STRATEGIES``), then
  MreOutlook (the plan report). Renewal and open-loop MRE covariances: MrePrediction.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

from activetrack.filters.measurement import TrackingFilter
from activetrack.filters.registry import filter_kind, make_filter
from activetrack.kernels import expect_particle_work
from activetrack.metrics import GospaWeights
from activetrack.models.base import as_linear
from activetrack.models.clutter import ClutteredSensor
from activetrack.planning.across_targets import (
    AcrossTargetsSettings,
    MultiTargetPlanner,
    ScenePlatform,
)
from activetrack.planning.cautious import CautiousController, CautiousPlanner
from activetrack.planning.criteria import PCRLB, POSITIONING, get_criterion
from activetrack.planning.decision import Planner, PlannerStrategy
from activetrack.planning.search_intensity import Surveillance
from activetrack.planning.strategies import (
    CautiousLocalisation,
    FixedSelection,
    HoldCourse,
    LinearDynamics,
    MreOutlook,
    MrePositioning,
    MrePrediction,
    MreSelection,
    PcrlbPlanning,
    PlatformSpec,
    RandomSelection,
    SensorEntry,
    TraceSelection,
)
from activetrack.scenarios.build import (
    build_motion_model,
    build_sensor,
    plan_settings,
    search_settings,
    steered_limits,
)
from activetrack.scenarios.schema import (
    EvaluationConfig,
    PlannerConfig,
    Scenario,
    SelectionConfig,
    SurveillanceConfig,
    TargetConfig,
)
from activetrack.scenarios.tracking import TrackingConfig, tracking_of
from activetrack.simulation.simulator import SimPlatform, SimTarget, Simulator
from activetrack.tracking.tracker import FilterSpec, Tracker, TrackPrior

__all__ = [
    "build_planner",
    "build_simulator",
    "build_tracker",
    "component_rngs",
    "scene_sensors",
    "scene_targets",
    "target_dynamics",
]


def target_dynamics(scenario: Scenario) -> LinearDynamics:
    """The first target's linear pv dynamics over one interval dt (the planners' F and Q)."""
    model = build_motion_model(scenario.target.motion)
    if not model.is_linear:
        raise ValueError(
            f"planner: PCRLB / MRE planning needs linear target dynamics (ncv, ncv_discrete, "
            f"constant_turn), got motion {scenario.target.motion.model!r}"
        )
    linear, dt = as_linear(model), scenario.dt
    return LinearDynamics(linear.transition_matrix(dt), linear.process_noise(dt), dt)


def component_rngs(seed: int, run: int | None = None) -> tuple[np.random.Generator, ...]:
    """(sim, tracker, planner, evaluator) generators: one stream each, fixed by seed and run."""
    ss = np.random.SeedSequence(seed if run is None else [seed, run])
    return tuple(np.random.default_rng(s) for s in ss.spawn(4))


def scene_targets(scenario: Scenario) -> list[TargetConfig]:
    """The scenario's targets in order (one or many)."""
    return list(scenario.targets)


def scene_sensors(source: Scenario | TrackingConfig) -> dict[str, tuple[str, ClutteredSensor]]:
    """Every sensor by id in the order of a scenario or tracker configuration: (platform id,
    the sensor in the scene: its field of view, clutter, and the tracker's gate unless the
    association is known)."""
    gate, known = source.tracker.tracks.gate_sigmas, source.known_association
    return {
        s.id: (p.id, ClutteredSensor.wrap(build_sensor(s), s, gate, not known))
        for p in source.platforms
        for s in p.sensors
    }


def build_simulator(scenario: Scenario, rng: np.random.Generator) -> Simulator:
    """The scenario's targets and platforms, drawing from ``rng``."""
    sensors = scene_sensors(scenario)
    targets = [
        SimTarget(
            t.id,
            build_motion_model(t.motion),
            np.array(t.prior.mean, dtype=float),
            t.prior.covariance(),
            None if t.initial_state is None else np.array(t.initial_state, dtype=float),
            t.birth,
            t.death,
        )
        for t in scene_targets(scenario)
    ]
    platforms = [
        SimPlatform(
            p.id,
            np.array(p.initial_state, dtype=float),
            p.limits if p.controllable else None,
            tuple((s.id, sensors[s.id][1]) for s in p.sensors),
        )
        for p in scenario.platforms
    ]
    return Simulator(targets, platforms, scenario.dt, scenario.steps, rng, scenario.random_streams)


def _gospa_weights(evaluation: EvaluationConfig) -> GospaWeights:
    """GOSPA's c, p and alpha of a scenario's ``evaluation`` (the tracker's report and the
    planner's expected GOSPA weigh by the metric that scores them)."""
    return GospaWeights(evaluation.cutoff, evaluation.order, evaluation.alpha)


def build_tracker(
    source: Scenario | TrackingConfig, rng: np.random.Generator, steps: int | None = None
) -> Tracker:
    """The tracker of a tracker configuration, or of a scenario (its configuration,
    :func:`~activetrack.scenarios.tracking.tracking_of`): its filter on every track, its
    targets as confirmed tracks from their priors, drawing from ``rng``. ``steps``: the epochs
    it will run (default: the configuration's), a hint to load the particle kernels now."""
    config = tracking_of(source) if isinstance(source, Scenario) else source
    cfg = config.tracker
    motion_cfg = cfg.motion
    if motion_cfg is None:  # the schema's rule
        raise ValueError("tracker.motion: required in a tracker configuration")
    model = build_motion_model(motion_cfg)
    kind = filter_kind(cfg.filter)
    steps = steps if steps is not None else config.steps
    if kind.particle_based and steps is not None:  # a long run loads the PF kernels now
        expect_particle_work(steps * cfg.particles)

    def make(x0: np.ndarray, P0: np.ndarray, t0: float) -> TrackingFilter:
        return make_filter(cfg.filter, model, x0, P0, cfg, rng, t0)

    many = kind.factory_many  # the filter's batch form, if it registered one

    def make_many(X0: np.ndarray, P0: np.ndarray, t0: float) -> Sequence[TrackingFilter]:
        assert many is not None
        return many(model, X0, P0, cfg, rng, t0=t0)

    priors = [
        TrackPrior(
            t.id,
            np.array(t.prior.mean, dtype=float),
            np.array(t.prior.covariance(), dtype=float),
            t.priority,
        )
        for t in config.targets
    ]
    return Tracker(
        model,
        motion_cfg.model,
        FilterSpec(cfg.filter, kind.particle_based, make, None if many is None else make_many),
        {sid: sensor for sid, (_, sensor) in scene_sensors(config).items()},
        priors,
        known_association=config.known_association,
        management=cfg.tracks,
        planner_samples=cfg.planner_samples,
        new_track_priority=config.new_track_priority,
        rng=rng,
        report=_gospa_weights(config.evaluation) if cfg.tracks.report == "gospa" else None,
    )


# --- the planner -------------------------------------------------------------------------------

# planner.selection.strategy -> the strategy object (sensors, selection section, generator).
SelectionFactory = Callable[
    [Sequence[SensorEntry], SelectionConfig, np.random.Generator], PlannerStrategy
]
SELECTION_STRATEGIES: dict[str, SelectionFactory] = {
    "mre": lambda sensors, cfg, rng: MreSelection(sensors, cfg.criterion, cfg.count),
    "trace": lambda sensors, cfg, rng: TraceSelection(sensors, cfg.count),
    "random": lambda sensors, cfg, rng: RandomSelection(sensors, cfg.criterion, cfg.count, rng),
    "fixed": lambda sensors, cfg, rng: FixedSelection(sensors, cfg.criterion, cfg.fixed_sensor),
}


def build_planner(scenario: Scenario, rng: np.random.Generator) -> Planner:
    """The scenario's planner (module docstring), drawing from ``rng``."""
    return Planner(build_strategies(scenario, rng), _ids(scenario), scenario.dt)


def build_strategies(scenario: Scenario, rng: np.random.Generator) -> tuple[PlannerStrategy, ...]:
    """The strategies a scenario's planner runs, in order (module docstring)."""
    cfg = scenario.planner
    controllable = tuple(p.id for p in scenario.platforms if p.controllable)
    beams = any(s.beam_width is not None for p in scenario.platforms for s in p.sensors)
    if beams or not scenario.known_association:
        return (build_across_targets(scenario, rng),)
    if not cfg.enabled:
        return (HoldCourse(controllable),)
    if controllable and cfg.search == "cautious":
        # Stop-and-measure localisation replaces manoeuvre planning.
        return (CautiousLocalisation(_cautious_controller(scenario)),)
    mre = (cfg.cost == "mre" and bool(controllable)) or cfg.selection.enabled
    if not controllable and not mre:
        return (HoldCourse(()),)
    dynamics = target_dynamics(scenario)
    platforms = _platform_specs(scenario)
    prior = None
    if cfg.mode == "open_loop":
        prior = (np.array(scenario.target.prior.mean), scenario.target.prior.covariance())

    def pcrlb() -> PcrlbPlanning:
        return PcrlbPlanning(
            plan_settings(cfg), platforms, dynamics, rng, mc_samples=cfg.mc_samples,
            open_loop_prior=prior,
        )  # fmt: skip

    if not mre:
        return (pcrlb(),)
    sensors = tuple(
        SensorEntry(s.id, p.id, build_sensor(s)) for p in scenario.platforms for s in p.sensors
    )
    predictor = MrePrediction(dynamics, prior)
    stages: list[PlannerStrategy] = [predictor]
    if controllable and cfg.cost == "pcrlb":
        stages.append(pcrlb())
    elif controllable:
        search = search_settings(cfg)
        stages.append(MrePositioning(cfg.criterion, search, platforms, dynamics.dt, cfg.horizon))
    criterion = cfg.criterion
    if cfg.selection.enabled:
        stages.append(SELECTION_STRATEGIES[cfg.selection.strategy](sensors, cfg.selection, rng))
        criterion = cfg.selection.criterion
    search_name = cfg.search if controllable and cfg.cost == "mre" else "none"
    stages.append(MreOutlook(_ids(scenario), sensors, predictor, criterion, search_name))
    return tuple(stages)


def _ids(scenario: Scenario) -> tuple[str, ...]:
    """The scenario's platform ids, in order."""
    return tuple(p.id for p in scenario.platforms)


def _platform_specs(scenario: Scenario) -> tuple[PlatformSpec, ...]:
    """Each platform's sensor models and, when controllable, its limits per epoch."""
    return tuple(
        PlatformSpec(
            p.id, tuple(build_sensor(s) for s in p.sensors), steered_limits(p, scenario.dt)
        )
        for p in scenario.platforms
    )


def _cautious_controller(scenario: Scenario) -> CautiousController:
    """The one robot's stop-and-measure controller (the rules checked its one bearing sensor
    and its limits)."""
    robot = next(p for p in scenario.platforms if p.controllable)
    c = scenario.planner.cautious
    if robot.limits is None:
        raise ValueError(f"platform {robot.id!r} is controllable but has no limits")
    # CautiousConfig's fields are the planner's parameters (beta, c_d, t_m, r_min, tail, ...).
    sigma_s, prior_cov = robot.sensors[0].sigma, scenario.target.prior.covariance()
    planner = CautiousPlanner(sigma_s, prior_cov, **c.model_dump())
    return CautiousController(robot.id, robot.limits.v_max, scenario.dt, planner)


def _cost_kind(cfg: PlannerConfig) -> str:
    """``planner.cost``, or the other kind when the criterion does not apply to it (only
    possible with the planner off or no controllable platform: the rules check the rest)."""
    crit = get_criterion(cfg.criterion, PCRLB, POSITIONING, what="planner.criterion")
    if cfg.cost == "pcrlb" and not crit.applies_to(PCRLB):
        return "mre"
    if cfg.cost == "mre" and not crit.applies_to(POSITIONING):
        return "pcrlb"
    return cfg.cost


def surveillance_of(cfg: SurveillanceConfig | None) -> Surveillance | None:
    """``planner.targets.surveillance`` as the planner reads it (None: no search)."""
    if cfg is None:
        return None
    x0, x1, y0, y1 = cfg.region
    return Surveillance(
        (x0, x1, y0, y1),
        cfg.birth_rate,
        cfg.cell_size,
        cfg.births,
        tuple(cfg.edges),
        cfg.birth_speed,
    )


def build_across_targets(scenario: Scenario, rng: np.random.Generator) -> MultiTargetPlanner:
    """Planning across targets for the scene: its platforms with their sensors in the scene
    and, where the planner steers them, their limits."""
    cfg = scenario.planner
    sensors = scene_sensors(scenario)
    platforms = [
        ScenePlatform(
            p.id,
            tuple((s.id, sensors[s.id][1]) for s in p.sensors),
            p.controllable,
            steered_limits(p, scenario.dt) if cfg.enabled else None,
        )
        for p in scenario.platforms
    ]
    steering = any(p.limits is not None for p in platforms)
    settings = AcrossTargetsSettings(
        cost_kind=_cost_kind(cfg),
        criterion=cfg.criterion,
        horizon=cfg.horizon,
        search=search_settings(cfg) if steering else None,
        mc_samples=cfg.mc_samples,
        max_iterations=cfg.max_sensor_iterations,
        aggregate=cfg.targets.aggregate,
        assignment=cfg.targets.assignment,
        objective=cfg.targets.objective,
        gospa=_gospa_weights(scenario.evaluation),
        surveillance=surveillance_of(cfg.targets.surveillance),
        pointing=cfg.targets.pointing,
        clutter_gate=cfg.targets.clutter_gate,
        existence_terminate=scenario.tracker.tracks.existence_terminate,
        existence_terminate_prior=scenario.tracker.tracks.existence_terminate_prior,
    )
    return MultiTargetPlanner(platforms, target_dynamics(scenario), settings, rng)
