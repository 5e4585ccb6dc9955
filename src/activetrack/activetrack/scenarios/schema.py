"""The scenario file schema (YAML): its sections as pydantic classes, one schema for the batch
loop, the experiments and the nodes. Units: m, s, rad; states pv (x, xdot, y, ydot) unless the
motion model says otherwise. Unknown keys are errors (a typo must not fall back to a default).

The classes check shape and the rules inside one section that need no component (ranges, sizes
bounded by :mod:`activetrack.limits`, dimensions, positive definite covariances); the rules
that ask registries or components are :mod:`activetrack.scenarios.rules`, run by the loader
after these (``Scenario.model_validate`` alone checks the shape only). The sensor entries are
the registered kinds' configs (:mod:`.registry`).
"""

from __future__ import annotations

from typing import Annotated, Any, Literal

import numpy as np
from pydantic import Field, GetCoreSchemaHandler, StrictBool, field_validator, model_validator
from pydantic_core import core_schema

from activetrack import limits
from activetrack.checks import require_spd
from activetrack.limits import MAX_SENSORS  # in PlatformConfig, whose field limits hides the module
from activetrack.regions import check_surveillance
from activetrack.scenarios.fields import (
    MOTION_STATE,
    PV,
    Acceleration,
    BearingSigma,
    Covariance,
    Divisions,
    Dt,
    Dwell,
    FiniteFloat,
    GridSize,
    HeadingChange,
    Horizon,
    Measurements,
    NoisePsd,
    Particles,
    PositiveSpeed,
    PositiveTurnRate,
    RangeM,
    RangeSigma,
    RateSigma,
    Roughening,
    Samples,
    SectorLevels,
    Seed,
    SensorConfigBase,
    SensorCount,
    SensorIterations,
    Speed,
    Steps,
    Strict,
    TurnRate,
    TurnRateStd,
    Variance,
    check_state,
    float_range,
    identifier,
)
from activetrack.scenarios.plugins import Plugins
from activetrack.scenarios.registry import on_registry_change, sensor_config_union

# --- motion models -----------------------------------------------------------------------------


class NcvMotion(Strict):
    """Continuous white-noise acceleration, PSD q (Hernandez sec. 5.1, l)."""

    model: Literal["ncv"]
    q: NoisePsd


class NcvDiscreteMotion(Strict):
    """Discrete noise gain G with sigma_x, sigma_y (Ramdaras eq. 3-4)."""

    model: Literal["ncv_discrete"]
    sigma_x: Acceleration
    sigma_y: Acceleration


class ConstantTurnMotion(Strict):
    """Constant turn with known rate omega (Valverde eq. 30-37)."""

    model: Literal["constant_turn"]
    omega: TurnRate
    q: NoisePsd


class CircularMotionConfig(Strict):
    """Circular motion, state (psi, px, py, omega, v) (Valverde eq. 15-28)."""

    model: Literal["circular"]
    sigma_omega: TurnRateStd
    sigma_v: Speed


class CircularKnownOmegaMotion(Strict):
    model: Literal["circular_known_omega"]
    omega: TurnRate
    sigma_v: Speed


MotionConfig = Annotated[
    NcvMotion
    | NcvDiscreteMotion
    | ConstantTurnMotion
    | CircularMotionConfig
    | CircularKnownOmegaMotion,
    Field(discriminator="model"),
]


# --- sensors -----------------------------------------------------------------------------------
# The built-in kinds' entries (registered with their sensor classes in scenarios.build).


class BearingSensorConfig(SensorConfigBase):
    kind: Literal["bearing"]
    sigma: BearingSigma  # rad


class AmbiguousBearingSensorConfig(SensorConfigBase):
    kind: Literal["ambiguous_bearing"]
    sigma: BearingSigma  # rad


class RangeBearingSensorConfig(SensorConfigBase):
    kind: Literal["range_bearing"]
    sigma_r: RangeSigma  # m
    sigma_b: BearingSigma  # rad


class RangeRateBearingSensorConfig(SensorConfigBase):
    kind: Literal["range_rate_bearing"]
    sigma_r: RangeSigma  # m
    sigma_rr: RateSigma  # m/s
    sigma_b: BearingSigma  # rad


def _no_sensor_kind(value: Any) -> Any:
    raise ValueError("no sensor kind is registered (activetrack.scenarios.registry)")


class _RegisteredSensors:
    """A ``sensors:`` entry validates as the discriminated union of the registered configs
    (``registry.sensor_config_union``), looked up whenever the schema is (re)built."""

    def __get_pydantic_core_schema__(
        self, source: Any, handler: GetCoreSchemaHandler
    ) -> core_schema.CoreSchema:
        union = sensor_config_union()
        if union is None:  # before the built-in kinds are registered (scenarios.build)
            return core_schema.no_info_plain_validator_function(_no_sensor_kind)
        return handler.generate_schema(union)


SensorConfig = Annotated[SensorConfigBase, _RegisteredSensors()]


def _rebuild_sensor_models() -> None:
    """Rebuild the models holding sensor entries after a kind was (un)registered."""
    PlatformConfig.model_rebuild(force=True)
    Scenario.model_rebuild(force=True)


on_registry_change(_rebuild_sensor_models)

# --- platforms ---------------------------------------------------------------------------------


class ManoeuvreLimits(Strict):
    """Per decision epoch: heading change within +-dpsi_max, speed change within +-dv_max and
    speed within [v_min, v_max] (Hernandez sec. 3.3.1, 5.1). Ramdaras' limits (sec. 5: max
    longitudinal acceleration a_max, heading rate psi_rate_max) map to dv_max = a_max T and
    dpsi_max = psi_rate_max T; give either pair."""

    dpsi_max: HeadingChange | None = None
    dv_max: Speed | None = None
    a_max: Acceleration | None = None
    psi_rate_max: PositiveTurnRate | None = None
    v_min: Speed = 0.0
    v_max: PositiveSpeed

    @model_validator(mode="after")
    def _one_pair(self):
        hernandez = self.dpsi_max is not None and self.dv_max is not None
        ramdaras = self.a_max is not None and self.psi_rate_max is not None
        if hernandez == ramdaras:
            raise ValueError(
                "give exactly one of the pairs (dpsi_max, dv_max) or (a_max, psi_rate_max)"
            )
        if not self.v_min <= self.v_max:
            raise ValueError(f"v_min: must not exceed v_max ({self.v_max}), got {self.v_min}")
        return self

    def per_epoch(self, dt: float) -> tuple[float, float]:
        """(dpsi_max, dv_max) for one decision interval of dt seconds."""
        if self.dpsi_max is not None and self.dv_max is not None:
            return self.dpsi_max, self.dv_max
        assert self.psi_rate_max is not None and self.a_max is not None  # the validator's rule
        return self.psi_rate_max * dt, self.a_max * dt


class PlatformConfig(Strict):
    id: Annotated[str, identifier("a platform id")]
    initial_state: list[FiniteFloat] = Field(min_length=4, max_length=4)  # pv
    controllable: bool = False
    limits: ManoeuvreLimits | None = None
    sensors: list[SensorConfig] = Field(min_length=1, max_length=MAX_SENSORS)

    @field_validator("initial_state")
    @classmethod
    def _state(cls, value):
        check_state(value, PV)
        return value

    @model_validator(mode="after")
    def _limits_if_controllable(self):
        if self.controllable and self.limits is None:
            raise ValueError("limits: a controllable platform needs limits")
        return self


# --- target ------------------------------------------------------------------------------------


class PriorConfig(Strict):
    """Gaussian prior of the target state: mean and either cov (full) or var (diagonal)."""

    mean: list[FiniteFloat] = Field(min_length=1, max_length=limits.MAX_STATE_DIM)
    cov: list[list[Covariance]] | None = Field(default=None, max_length=limits.MAX_STATE_DIM)
    var: list[Variance] | None = Field(default=None, max_length=limits.MAX_STATE_DIM)

    @model_validator(mode="after")
    def _one_cov(self):
        if (self.cov is None) == (self.var is None):
            raise ValueError("give exactly one of cov (full matrix) or var (diagonal)")
        field = "cov" if self.cov is not None else "var"
        n = len(self.mean)
        if self.cov is not None:
            shape = (len(self.cov), *{len(row) for row in self.cov})
            if shape != (n, n):
                raise ValueError(
                    f"cov: must be {n}x{n} to match mean, got rows of lengths "
                    f"{[len(row) for row in self.cov]}"
                )
        elif self.var is not None and len(self.var) != n:
            raise ValueError(f"var: must have {n} entries to match mean, got {len(self.var)}")
        try:  # the filters' own check: symmetric to 1e-9 relative, Cholesky succeeds
            P = require_spd("the covariance", self.covariance())
        except ValueError as exc:
            raise ValueError(f"{field}: {exc}") from None
        smallest = float(np.linalg.eigvalsh(P)[0])
        if not smallest >= limits.MIN_PRIOR_VARIANCE:
            raise ValueError(
                f"{field}: the covariance's smallest eigenvalue must be >= "
                f"{limits.MIN_PRIOR_VARIANCE:g} (activetrack.limits), got {smallest:.3g}"
            )
        return self

    def covariance(self) -> np.ndarray:
        return np.diag(self.var) if self.var is not None else np.array(self.cov, dtype=float)


class TargetConfig(Strict):
    id: Annotated[str, identifier("the target id")] = "t1"
    motion: MotionConfig
    prior: PriorConfig
    # Truth at k = 0: a fixed state, or drawn from the prior with the simulator's generator.
    initial_state: list[FiniteFloat] | None = Field(default=None, max_length=limits.MAX_STATE_DIM)
    # Multi-target scenarios: the target exists for epochs birth <= k < death (its truth at
    # ``birth`` is initial_state or a draw from the prior); priority weighs it in the planner's
    # weighted sum. Targets present at epoch 0 are tracked from their priors.
    birth: Annotated[int, Field(ge=0, le=limits.MAX_STEPS)] = 0
    death: Annotated[int, Field(ge=1, le=limits.MAX_STEPS)] | None = None
    priority: Annotated[float, float_range(gt=0, hi=1e6)] = 1.0

    @model_validator(mode="after")
    def _dims(self):
        model = self.motion.model
        names = MOTION_STATE[model]
        states = [("prior.mean", self.prior.mean)]
        if self.initial_state is not None:
            states.append(("initial_state", self.initial_state))
        for field, values in states:
            if len(values) != len(names):
                raise ValueError(
                    f"{field}: must have {len(names)} entries {names} for motion {model}, got "
                    f"{len(values)}"
                )
        for field, values in states:
            try:
                check_state(values, names)
            except ValueError as exc:
                raise ValueError(f"{field}: {exc}") from None
        return self


# --- tracker and planner -----------------------------------------------------------------------


class TrackManagementConfig(Strict):
    """JPDA gating and M-of-N track management (the rules: activetrack.tracking.management);
    tracks from detections start with velocity 0 and standard deviation ``init_speed_std``
    (``initiate: false``: only the priors' tracks). Probability of existence: a tentative
    track is confirmed at M of N and ``existence_confirm``, deleted past N looks below
    ``existence_delete``; a confirmed track is terminated below ``existence_terminate``
    (Musicki's IPDA practice: confirm ~0.9-0.95, terminate ~0.01-0.05; ``existence_survival``
    per epoch predicts it), one from a prior below
    ``existence_terminate_prior`` (lower: its target may never be picked up again, a bearing
    starts no track and a beam looks only where tracks are). ``oversize_cluster``: what a
    cluster too large for exact JPDA does (an error, or pruned: counted). ``report``: which
    confirmed tracks make the tracker's estimate of the targets (what GOSPA scores):
    ``confirmed`` every one; ``gospa`` those whose reporting lowers their expected GOSPA with
    ``evaluation``'s c, p and alpha, by probability of existence and spread
    (:func:`activetrack.metrics.gospa_reported`: r > 1/2 for a well localised track); the
    others are withheld but still tracked and planned for."""

    gate_sigmas: Annotated[float, Field(gt=0, le=limits.MAX_GATE_SIGMAS)] = 3.5
    confirm_m: Annotated[int, Field(ge=1, le=100)] = 2
    confirm_n: Annotated[int, Field(ge=1, le=100)] = 3
    delete_misses: Annotated[int, Field(ge=1, le=1000)] = 4
    init_speed_std: Annotated[float, Field(gt=0, le=1e6)] = 10.0  # m/s
    max_position_std: Annotated[float, Field(gt=0, le=limits.MAX_RANGE)] = 1e5  # m
    max_tracks: Annotated[int, Field(ge=1, le=limits.MAX_TRACKS)] = 50
    initiate: StrictBool = True  # false: tracks only from the priors
    existence_confirm: Annotated[float, Field(gt=0, lt=1)] = 0.9
    existence_delete: Annotated[float, Field(ge=0, lt=1)] = 0.1  # tentative tracks
    existence_terminate: Annotated[float, Field(ge=0, lt=1)] = 0.02  # confirmed tracks
    existence_terminate_prior: Annotated[float, Field(ge=0, lt=1)] = 0.001  # from priors
    # IPDA's probability that a target lives on through an epoch (p11, Musicki et al. 1994):
    # the prediction of every track's existence; 1 for targets that never die.
    existence_survival: Annotated[float, Field(gt=0, le=1)] = 0.98
    # A JPDA cluster whose hypothesis net exceeds its memory bound (max_edges): "error" stops
    # the tracker with an error naming this field (exact JPDA everywhere), "prune" drops the
    # cluster's weakest gated pairs until it fits (activetrack.filters.jpda_prune; counted).
    oversize_cluster: Literal["error", "prune"] = "error"
    report: Literal["confirmed", "gospa"] = "confirmed"

    @model_validator(mode="after")
    def _m_of_n(self) -> TrackManagementConfig:
        if self.confirm_m > self.confirm_n:
            raise ValueError(
                f"confirm_m: must be <= confirm_n ({self.confirm_n}), got {self.confirm_m}"
            )
        for name in ("existence_delete", "existence_terminate", "existence_terminate_prior"):
            if getattr(self, name) >= self.existence_confirm:
                raise ValueError(
                    f"{name}: must be < existence_confirm ({self.existence_confirm}), "
                    f"got {getattr(self, name)}"
                )
        return self


class TrackerConfig(Strict):
    # A registered filter (activetrack.filters.registry): "ekf", "pf" or one of a plugin's.
    filter: str = "pf"
    # Options of particle-based filters (the built-in "pf"); other filters ignore them.
    particles: Particles = 10000
    resample: Literal["always", "ess"] = "always"
    ess_threshold: Annotated[float, Field(gt=0, le=1)] = 0.5
    roughening: Roughening = 0.0
    min_range: Literal["ignore", "negative"] = "ignore"
    # Motion model the filter assumes; None: the target's own.
    motion: MotionConfig | None = None
    # Equally weighted posterior samples handed to the planner for renewal (particle-based
    # filters only).
    planner_samples: Samples = 1000
    # Multi-target scenarios: gating, M-of-N confirmation and deletion, initiation.
    tracks: TrackManagementConfig = TrackManagementConfig()


class SelectionConfig(Strict):
    """Sensor selection (Ramdaras eq. 27): which sensors measure at each epoch."""

    enabled: bool = False
    strategy: Literal["mre", "random", "fixed", "trace"] = "mre"
    criterion: str = "det_pos"  # a criterion for MRE selection (planning.criteria)
    fixed_sensor: str | None = None
    count: SensorCount = 1


class CautiousConfig(Strict):
    """Beta-cautious greedy localisation (Vander Hook et al., Algorithm 1)."""

    beta: Annotated[float, Field(gt=0, lt=1)] = 0.1
    c_d: Annotated[float, Field(gt=0, lt=1)] = 0.1  # reduce both standard deviations by c_d
    t_m: Dwell = 60.0  # s stopped for each measurement
    r_min: RangeM = 1.0  # m, smallest standoff
    tail: Literal["two_sided", "one_sided"] = "two_sided"
    max_measurements: Measurements | None = None


class SurveillanceConfig(Strict):
    """Where targets not yet tracked may appear (search versus track): a rectangle ``region``
    ``[x_min, x_max, y_min, y_max]`` [m], ``birth_rate`` new targets per second over it, the
    ``cell_size`` [m] of the planner's grid of their intensity, and ``births``: ``uniform``
    over the region (the default), or ``edges``: along the named ``edges`` (``west``: x_min,
    ``east``: x_max, ``south``: y_min, ``north``: y_max), entering at ``birth_speed`` [m/s]
    inward, the planner's intensity drifting with them between epochs
    (:mod:`activetrack.planning.search_intensity`)."""

    region: Annotated[
        list[Annotated[float, Field(ge=-limits.MAX_RANGE, le=limits.MAX_RANGE)]],
        Field(min_length=4, max_length=4),
    ]
    birth_rate: Annotated[float, Field(ge=0, le=1e3)]
    cell_size: Annotated[float, Field(gt=0, le=limits.MAX_RANGE)] = 250.0
    births: Literal["uniform", "edges"] = "uniform"
    edges: Annotated[list[Literal["west", "east", "south", "north"]], Field(max_length=4)] = Field(
        default_factory=list
    )
    birth_speed: Annotated[float, Field(ge=0, le=limits.MAX_SPEED)] = 0.0

    @model_validator(mode="after")
    def _region(self) -> SurveillanceConfig:
        # the planner's own rules (activetrack.regions), so a file fails as a caller would
        check_surveillance(self.region, self.cell_size, self.births, self.edges, self.birth_speed)
        return self


class MultiTargetPlanConfig(Strict):
    """Planning across tracks.

    ``aggregate``: ``worst`` minimises the largest per-track cost (the worst target's b_k),
    ``weighted_sum`` the sum of per-track costs weighted by the target's ``priority`` (tracks
    started from detections weigh ``new_track_priority``). Only confirmed tracks count.
    ``assignment``: how sensors with a steerable beam (``beam_width``) are pointed, one track
    each per epoch: ``mre`` the optimal assignment of the per-pair MRE cost, ``random``
    uniformly (the baseline), ``nearest`` the closest track. ``objective``: ``criterion``
    plans on ``planner.criterion`` of the confirmed tracks' bounds, combined by ``aggregate``;
    ``gospa`` on the expected GOSPA of every confirmed track (localisation weighted by its
    probability of existence, plus c^p / alpha per expected missed and false target, c, p and
    alpha from ``evaluation``; :mod:`activetrack.planning.expected_gospa`) over ``horizon``
    epochs by rollout, beams assigned on the same cost. ``surveillance`` (with ``gospa``):
    beams may also search the region for targets not yet tracked, valued in the same GOSPA
    units (absent: beams serve tracks only); with ``assignment: random`` beams draw among the
    tracks and the search pointings. ``pointing`` (with ``assignment: mre``): ``track``
    points each beam at the track assigned to it and credits that track alone; ``footprint``
    credits every track a beam holds (the tracker updates each track whose predicted position
    lies in the scan's sector) and centres each beam, greedily in turn, where it lowers the
    tracks' summed criterion most, on one track or between several (objective ``criterion``
    and aggregate ``weighted_sum`` only). ``clutter_gate``: the information reduction factor
    of clutter in a planned look (:mod:`activetrack.models.clutter`): ``measurement`` one q
    per sensor, of the density whitened by R; ``innovation`` q of the tracker's gate on the
    track's innovation covariance S = H P H^T + R at the planned geometry (a wider gate holds
    more false alarms; Kershaw & Evans 1994).
    """

    aggregate: Literal["worst", "weighted_sum"] = "worst"
    assignment: Literal["mre", "random", "nearest"] = "mre"
    objective: Literal["criterion", "gospa"] = "criterion"
    pointing: Literal["track", "footprint"] = "track"
    clutter_gate: Literal["measurement", "innovation"] = "measurement"
    new_track_priority: Annotated[float, Field(gt=0, le=1e6)] = 1.0
    surveillance: SurveillanceConfig | None = None


class PlannerConfig(Strict):
    enabled: bool = True
    cost: Literal["pcrlb", "mre"] = "pcrlb"
    # A criterion for PCRLB planning (cost pcrlb) or MRE positioning (cost mre), planning.criteria.
    criterion: str = "b_k"
    horizon: Horizon = 1
    search: Literal["grid", "quadrant", "sector", "evolution", "cautious"] = "quadrant"
    grid_size: GridSize = 101
    quadrant_divisions: Divisions = 6
    quadrant_patience: Divisions = 6
    sector_levels: SectorLevels = 3
    mode: Literal["renewal", "open_loop"] = "renewal"
    # J_Z's Gaussian draws (eq. 8) for a Gaussian track or the open-loop prior; particle tracks
    # in renewal give their own (tracker.planner_samples).
    mc_samples: Samples = 1000
    max_sensor_iterations: SensorIterations = 10
    selection: SelectionConfig = SelectionConfig()
    cautious: CautiousConfig = CautiousConfig()
    # Multi-target scenarios: costs over tracks, beam assignment.
    targets: MultiTargetPlanConfig = MultiTargetPlanConfig()

    @field_validator("horizon", mode="before")
    @classmethod
    def _horizon(cls, value: object) -> int:
        """R of the receding horizon (1: single-step, eq. 11; 2: two-step DP, eq. 13-15; R:
        eq. 16, the DP nested R deep or evolution): an integer, neither a bool nor a fraction."""
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        top = limits.MAX_HORIZON
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= top:
            raise ValueError(
                f"must be an integer in [1, {top}] (the planning horizon R: 1 "
                f"single-step, 2 two-step, 3 three-step, ...), got {value!r}"
            )
        return value


class EvaluationConfig(Strict):
    """OSPA (Schuhmacher et al. 2008) and GOSPA (Rahmathullah et al. 2017) parameters:
    cut-off ``c`` [m], order ``p`` and GOSPA's ``alpha`` (2: the metric splits into
    localisation, missed and false-target terms)."""

    cutoff: Annotated[float, Field(gt=0, le=limits.MAX_RANGE)] = 1000.0
    order: Annotated[float, Field(ge=1, le=100)] = 2.0
    alpha: Annotated[float, Field(gt=0, le=2)] = 2.0


class GraphConfig(Strict):
    """How the ROS graph runner treats node processes (``activetrack run --processes``).

    A restartable node whose process dies is started again (at most ``max_restarts`` times);
    the death of any other node fails the run. Only the planner can be restarted: it keeps no
    state a new one could not rebuild from the latched track and platform states, whereas a
    restarted tracker or simulator would lose the run."""

    restartable: list[Literal["planner"]] = Field(default=["planner"])
    max_restarts: Annotated[int, Field(ge=0, le=10)] = 3


def check_platform_ids(platforms: list) -> list:
    """Platform ids unique, sensor ids unique across platforms, at most MAX_SENSORS sensors in
    all (a scenario's and a tracker configuration's ``platforms``)."""
    ids = [p.id for p in platforms]
    sensor_ids = [s.id for p in platforms for s in p.sensors]
    for what, values in (("platform", ids), ("sensor", sensor_ids)):
        dupes = sorted({v for v in values if values.count(v) > 1})
        if dupes:
            raise ValueError(f"{what} ids must be unique, repeated: {dupes}")
    if len(sensor_ids) > limits.MAX_SENSORS:
        raise ValueError(
            f"at most {limits.MAX_SENSORS} sensors in total (activetrack.limits), got "
            f"{len(sensor_ids)}"
        )
    return platforms


class Scenario(Strict):
    name: Annotated[str, identifier("the name (it names the run folder)", limits.MAX_NAME_LENGTH)]
    description: str = Field(default="", max_length=limits.MAX_DESCRIPTION_LENGTH)
    # Modules that register kinds, filters, criteria; imported first (scenarios.plugins).
    plugins: Plugins = Field(default=[])
    seed: Seed = 0
    # common: each target's motion, each sensor's detections and clutter draw from their own
    # streams (policies compared on the same world); sequential: one generator
    # (activetrack.simulation.streams).
    random_streams: Literal["common", "sequential"] = "common"
    dt: Dt  # s between measurement / decision epochs (T)
    steps: Steps  # epochs k = 1..steps
    # The targets: one (the papers) or many; a file may give a single one as ``target:``.
    targets: list[TargetConfig] = Field(min_length=1, max_length=limits.MAX_TARGETS)
    platforms: list[PlatformConfig] = Field(min_length=1, max_length=limits.MAX_PLATFORMS)
    tracker: TrackerConfig = TrackerConfig()
    planner: PlannerConfig = PlannerConfig()
    evaluation: EvaluationConfig = EvaluationConfig()
    graph: GraphConfig = GraphConfig()

    @model_validator(mode="before")
    @classmethod
    def _one_target(cls, data: Any) -> Any:
        """``target:`` (one target) is ``targets:`` with that one entry."""
        if isinstance(data, dict) and "target" in data:
            if "targets" in data:
                raise ValueError("target: give target (one) or targets (a list), not both")
            one = data["target"]
            data = {k: v for k, v in data.items() if k != "target"}
            data["targets"] = [one]
        return data

    @field_validator("platforms")
    @classmethod
    def _unique_ids(cls, platforms):
        return check_platform_ids(platforms)

    @property
    def known_association(self) -> bool:
        """Whether every detection is known to be the one target's: one target present from
        epoch 0 to the end and no sensor with clutter. The tracker then runs its filter on the
        detections directly; otherwise it associates them (JPDA) and manages tracks
        (activetrack.tracking), and the planner plans across tracks."""
        t = self.targets[0]
        clutter = any(c.clutter_density > 0 for p in self.platforms for c in p.sensors)
        return len(self.targets) == 1 and t.birth == 0 and t.death is None and not clutter

    @property
    def target(self) -> TargetConfig:
        """The first target: a one-target scenario's, and whose motion the tracker assumes
        unless ``tracker.motion`` says otherwise."""
        return self.targets[0]
