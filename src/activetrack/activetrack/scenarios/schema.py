"""The scenario file schema (YAML), validated on load with pydantic.

One schema for the batch loop, the experiment runners and the ROS nodes. Units: metres,
seconds, radians. States are pv vectors (x, xdot, y, ydot) unless the motion model says
otherwise.

Unknown keys are errors (a typo must not silently fall back to a default). Every rule the
simulator, tracker and planner cores would enforce when they are built or in their first
epochs is checked here, cross-field rules included (``Scenario._cross_field_rules``), so a
scenario that loads runs. Sizes and magnitudes are bounded by :mod:`activetrack.limits`.
"""

from __future__ import annotations

import math
import re
from typing import TYPE_CHECKING, Annotated, Any, Literal, Self

import numpy as np
from pydantic import (
    BaseModel,
    ConfigDict,
    Field,
    GetCoreSchemaHandler,
    field_validator,
    model_validator,
)
from pydantic_core import core_schema

from activetrack.limits import (
    MAX_ACCELERATION,
    MAX_ANGLE,
    MAX_BEARING_SIGMA,
    MAX_CLUTTER_DENSITY,
    MAX_DESCRIPTION_LENGTH,
    MAX_DT,
    MAX_DURATION,
    MAX_DWELL,
    MAX_GRID_SIZE,
    MAX_HORIZON,
    MAX_ID_LENGTH,
    MAX_MEASUREMENTS,
    MAX_NAME_LENGTH,
    MAX_PARTICLES,
    MAX_PLANNER_BATCH,
    MAX_PLATFORMS,
    MAX_POSITION,
    MAX_PRIOR_VARIANCE,
    MAX_Q,
    MAX_QUADRANT_DIVISIONS,
    MAX_RANGE,
    MAX_ROUGHENING,
    MAX_SAMPLES,
    MAX_SEARCH_EVALUATIONS,
    MAX_SECTOR_LEVELS,
    MAX_SEED,
    MAX_SENSOR_ITERATIONS,
    MAX_SENSORS,
    MAX_SPEED,
    MAX_STATE_DIM,
    MAX_STEPS,
    MAX_TARGETS,
    MAX_TURN_RATE,
    MIN_DT,
    MIN_PARTICLES_FOR_PLANNING,
    MIN_PRIOR_VARIANCE,
    MIN_SIGMA,
)
from activetrack.models.sensors import (
    AmbiguousBearingSensor,
    BearingSensor,
    RangeBearingSensor,
    RangeRateBearingSensor,
)
from activetrack.scenarios.multitarget_config import (
    EvaluationConfig,
    MultiTargetPlanConfig,
    TrackManagementConfig,
    multitarget_problems,
)
from activetrack.scenarios.plugins import MAX_PLUGINS, check_plugin_names
from activetrack.scenarios.registry import (
    on_registry_change,
    register_sensor,
    sensor_config_union,
)


def _range(
    lo: float | None = None,
    hi: float | None = None,
    *,
    gt: float | None = None,
    lt: float | None = None,
) -> Any:
    """The bounds of a finite float field (``Annotated[float, _range(...)]``)."""
    return Field(ge=lo, le=hi, gt=gt, lt=lt, allow_inf_nan=False)


FiniteFloat = Annotated[float, _range()]
# Magnitudes (activetrack.limits).
Speed = Annotated[float, _range(0, MAX_SPEED)]  # m/s
PositiveSpeed = Annotated[float, _range(gt=0, hi=MAX_SPEED)]
Acceleration = Annotated[float, _range(0, MAX_ACCELERATION)]  # m/s^2
NoisePsd = Annotated[float, _range(0, MAX_Q)]  # m^2/s^3
TurnRate = Annotated[float, _range(-MAX_TURN_RATE, MAX_TURN_RATE)]  # rad/s
TurnRateStd = Annotated[float, _range(0, MAX_TURN_RATE)]
PositiveTurnRate = Annotated[float, _range(gt=0, hi=MAX_TURN_RATE)]
# rad; a turn beyond pi is one the other way
HeadingChange = Annotated[float, _range(gt=0, hi=math.pi)]
RangeM = Annotated[float, _range(0, MAX_RANGE)]  # m
BearingSigma = Annotated[float, _range(MIN_SIGMA, MAX_BEARING_SIGMA)]  # rad
RangeSigma = Annotated[float, _range(MIN_SIGMA, MAX_RANGE)]  # m
RateSigma = Annotated[float, _range(MIN_SIGMA, MAX_SPEED)]  # m/s
Variance = Annotated[float, _range(0, MAX_PRIOR_VARIANCE)]
Covariance = Annotated[float, _range(-MAX_PRIOR_VARIANCE, MAX_PRIOR_VARIANCE)]
Dt = Annotated[float, _range(MIN_DT, MAX_DT)]  # s
Dwell = Annotated[float, _range(0, MAX_DWELL)]  # s
Roughening = Annotated[float, _range(0, MAX_ROUGHENING)]


def _count(lo: int, hi: int) -> Any:
    """The bounds of an integer field (``Annotated[int, _count(lo, hi)]``)."""
    return Field(ge=lo, le=hi)


Particles = Annotated[int, _count(1, MAX_PARTICLES)]
Samples = Annotated[int, _count(1, MAX_SAMPLES)]
SensorCount = Annotated[int, _count(1, MAX_SENSORS)]
Horizon = Annotated[int, _count(1, MAX_HORIZON)]
GridSize = Annotated[int, _count(3, MAX_GRID_SIZE)]
Divisions = Annotated[int, _count(1, MAX_QUADRANT_DIVISIONS)]
SectorLevels = Annotated[int, _count(1, MAX_SECTOR_LEVELS)]
SensorIterations = Annotated[int, _count(1, MAX_SENSOR_ITERATIONS)]
Measurements = Annotated[int, _count(1, MAX_MEASUREMENTS)]
Seed = Annotated[int, _count(0, MAX_SEED)]
Steps = Annotated[int, _count(1, MAX_STEPS)]


# Scenario names become folder names (runs/<name>-<time>), ids go into messages and plots.
_IDENTIFIER = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]*")


def _identifier(what: str, value: str, max_length: int) -> str:
    if not (len(value) <= max_length and _IDENTIFIER.fullmatch(value)):
        shown = value if len(value) <= 40 else value[:40] + "..."
        raise ValueError(
            f"{what} must be 1-{max_length} characters of letters, digits, '_', '-' and '.', "
            f"not starting with '.', got {shown!r}"
        )
    return value


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


# --- motion models -----------------------------------------------------------------------------


class NcvMotion(_Strict):
    """Continuous white-noise acceleration, PSD q (Hernandez sec. 5.1, l)."""

    model: Literal["ncv"]
    q: NoisePsd


class NcvDiscreteMotion(_Strict):
    """Discrete noise gain G with sigma_x, sigma_y (Ramdaras eq. 3-4)."""

    model: Literal["ncv_discrete"]
    sigma_x: Acceleration
    sigma_y: Acceleration


class ConstantTurnMotion(_Strict):
    """Constant turn with known rate omega (Valverde eq. 30-37)."""

    model: Literal["constant_turn"]
    omega: TurnRate
    q: NoisePsd


class CircularMotionConfig(_Strict):
    """Circular motion, state (psi, px, py, omega, v) (Valverde eq. 15-28)."""

    model: Literal["circular"]
    sigma_omega: TurnRateStd
    sigma_v: Speed


class CircularKnownOmegaMotion(_Strict):
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

PV = ("x", "xdot", "y", "ydot")
# State of each motion model (the cores' ``state_names``).
MOTION_STATE = {
    "ncv": PV,
    "ncv_discrete": PV,
    "constant_turn": PV,
    "circular": ("psi", "px", "py", "omega", "v"),
    "circular_known_omega": ("psi", "px", "py", "v"),
}
MOTION_STATE_DIM = {model: len(names) for model, names in MOTION_STATE.items()}
# Linear dynamics on a pv state: what PCRLB / MRE planning and the cautious planner need.
PV_MODELS = ("ncv", "ncv_discrete", "constant_turn")
_STATE_BOUND = {
    "x": MAX_POSITION,
    "y": MAX_POSITION,
    "px": MAX_POSITION,
    "py": MAX_POSITION,
    "xdot": MAX_SPEED,
    "ydot": MAX_SPEED,
    "v": MAX_SPEED,
    "psi": MAX_ANGLE,
    "omega": MAX_TURN_RATE,
}


def _check_state(values, names) -> None:
    """Each entry within the bound of its state component (``_STATE_BOUND``)."""
    for i, (value, name) in enumerate(zip(values, names, strict=False)):
        bound = _STATE_BOUND[name]
        if abs(value) > bound:
            raise ValueError(
                f"entry {i} ({name}) must be within +-{bound:g} (activetrack.limits), got {value!r}"
            )


def _position(values, model: str) -> tuple[float, float]:
    names = MOTION_STATE[model]
    ix = names.index("x") if "x" in names else names.index("px")
    iy = names.index("y") if "y" in names else names.index("py")
    return float(values[ix]), float(values[iy])


# --- sensors -----------------------------------------------------------------------------------


class SensorConfigBase(_Strict):
    """Fields of every sensor kind: its id and detection model (pd inside [r_min, r_max],
    Hernandez sec. 2.3, Ramdaras eq. 14-22). A kind's config derives from this, adds
    ``kind: Literal["<kind>"]`` and its own fields, and is registered with its sensor class
    (:func:`activetrack.scenarios.registry.register_sensor`)."""

    id: str
    pd: Annotated[float, Field(gt=0, le=1)] = 1.0
    r_min: RangeM = 0.0
    r_max: Annotated[float, Field(gt=0)] = math.inf  # inf: no maximum range
    # Multi-target scenarios only (scenarios.multitarget_config): Poisson false alarms per
    # unit of z (per rad; per m rad for range-bearing) over the field of view, which is a
    # bearing sector fov_width wide centred fov_centre off the platform's heading (None: all
    # around), or a steerable beam beam_width wide the planner points at one track per epoch.
    clutter_density: Annotated[float, _range(0, MAX_CLUTTER_DENSITY)] = 0.0
    fov_centre: Annotated[float, _range(-math.pi, math.pi)] = 0.0
    fov_width: Annotated[float, _range(gt=0, hi=2 * math.pi)] | None = None
    beam_width: Annotated[float, _range(gt=0, hi=2 * math.pi)] | None = None
    if TYPE_CHECKING:
        kind: str  # a field of every subclass, as Literal["<kind>"]

        # The kind's own fields (sigma, sigma_r, ...): the registry decides which at run time.
        def __getattr__(self, name: str) -> Any: ...

    @field_validator("id")
    @classmethod
    def _id(cls, value: str) -> str:
        return _identifier("a sensor id", value, MAX_ID_LENGTH)

    @model_validator(mode="after")
    def _ranges(self) -> Self:
        if math.isfinite(self.r_max) and self.r_max > MAX_RANGE:
            raise ValueError(
                f"r_max: must be <= {MAX_RANGE:g} m or .inf (no maximum), got {self.r_max!r}"
            )
        if not self.r_min < self.r_max:
            raise ValueError(f"r_max: must be greater than r_min ({self.r_min}), got {self.r_max}")
        return self


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


# The built-in kinds, registered like any other (the order is that of the error messages).
register_sensor(BearingSensor, BearingSensorConfig)
register_sensor(AmbiguousBearingSensor, AmbiguousBearingSensorConfig)
register_sensor(RangeBearingSensor, RangeBearingSensorConfig)
register_sensor(RangeRateBearingSensor, RangeRateBearingSensorConfig)


class _RegisteredSensors:
    """A ``sensors:`` entry validates as the discriminated union of the registered configs
    (``registry.sensor_config_union``), looked up whenever the schema is (re)built."""

    def __get_pydantic_core_schema__(
        self, source: Any, handler: GetCoreSchemaHandler
    ) -> core_schema.CoreSchema:
        return handler.generate_schema(sensor_config_union())


SensorConfig = Annotated[SensorConfigBase, _RegisteredSensors()]


def _rebuild_sensor_models() -> None:
    """Rebuild the models holding sensor entries after a kind was (un)registered."""
    PlatformConfig.model_rebuild(force=True)
    Scenario.model_rebuild(force=True)


on_registry_change(_rebuild_sensor_models)
BEARING_KINDS = ("bearing", "ambiguous_bearing")

# --- platforms ---------------------------------------------------------------------------------


class ManoeuvreLimits(_Strict):
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


class PlatformConfig(_Strict):
    id: str
    initial_state: list[FiniteFloat] = Field(min_length=4, max_length=4)  # pv
    controllable: bool = False
    limits: ManoeuvreLimits | None = None
    sensors: list[SensorConfig] = Field(min_length=1, max_length=MAX_SENSORS)

    @field_validator("id")
    @classmethod
    def _id(cls, value):
        return _identifier("a platform id", value, MAX_ID_LENGTH)

    @field_validator("initial_state")
    @classmethod
    def _state(cls, value):
        _check_state(value, PV)
        return value

    @model_validator(mode="after")
    def _limits_if_controllable(self):
        if self.controllable and self.limits is None:
            raise ValueError("limits: a controllable platform needs limits")
        return self


# --- target ------------------------------------------------------------------------------------


class PriorConfig(_Strict):
    """Gaussian prior of the target state: mean and either cov (full) or var (diagonal)."""

    mean: list[FiniteFloat] = Field(min_length=1, max_length=MAX_STATE_DIM)
    cov: list[list[Covariance]] | None = Field(default=None, max_length=MAX_STATE_DIM)
    var: list[Variance] | None = Field(default=None, max_length=MAX_STATE_DIM)

    @model_validator(mode="after")
    def _one_cov(self):
        from activetrack.checks import require_spd

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
        if not smallest >= MIN_PRIOR_VARIANCE:
            raise ValueError(
                f"{field}: the covariance's smallest eigenvalue must be >= "
                f"{MIN_PRIOR_VARIANCE:g} (activetrack.limits), got {smallest:.3g}"
            )
        return self

    def covariance(self) -> np.ndarray:
        return np.diag(self.var) if self.var is not None else np.array(self.cov, dtype=float)


class TargetConfig(_Strict):
    id: str = "t1"
    motion: MotionConfig
    prior: PriorConfig
    # Truth at k = 0: a fixed state, or drawn from the prior with the simulator's generator.
    initial_state: list[FiniteFloat] | None = Field(default=None, max_length=MAX_STATE_DIM)
    # Multi-target scenarios: the target exists for epochs birth <= k < death (its truth at
    # ``birth`` is initial_state or a draw from the prior); priority weighs it in the planner's
    # weighted sum. Targets present at epoch 0 are tracked from their priors.
    birth: Annotated[int, Field(ge=0, le=MAX_STEPS)] = 0
    death: Annotated[int, Field(ge=1, le=MAX_STEPS)] | None = None
    priority: Annotated[float, _range(gt=0, hi=1e6)] = 1.0

    @field_validator("id")
    @classmethod
    def _id(cls, value):
        return _identifier("the target id", value, MAX_ID_LENGTH)

    @model_validator(mode="after")
    def _dims(self):
        model = self.motion.model
        n = MOTION_STATE_DIM[model]
        if len(self.prior.mean) != n:
            raise ValueError(
                f"prior.mean: must have {n} entries {MOTION_STATE[model]} for motion {model}, "
                f"got {len(self.prior.mean)}"
            )
        if self.initial_state is not None and len(self.initial_state) != n:
            raise ValueError(
                f"initial_state: must have {n} entries {MOTION_STATE[model]} for motion "
                f"{model}, got {len(self.initial_state)}"
            )
        states = (("prior.mean", self.prior.mean), ("initial_state", self.initial_state))
        for field, values in states:
            if values is not None:
                try:
                    _check_state(values, MOTION_STATE[model])
                except ValueError as exc:
                    raise ValueError(f"{field}: {exc}") from None
        return self


# --- tracker and planner -----------------------------------------------------------------------


def _one_of(names: tuple[str, ...]) -> str:
    """``'a', 'b' or 'c'``: the allowed values as pydantic lists a Literal's."""
    shown = [repr(n) for n in names]
    return shown[0] if len(shown) == 1 else f"{', '.join(shown[:-1])} or {shown[-1]}"


def _particle_based(name: str) -> bool:
    """Whether the registered filter ``name`` is a particle filter (its posterior a weighted
    particle set: the particle options and rules below apply)."""
    from activetrack.filters.registry import filter_kind

    return filter_kind(name).particle_based


class TrackerConfig(_Strict):
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

    @field_validator("filter", mode="before")
    @classmethod
    def _filter(cls, value: object) -> str:
        from activetrack.filters.registry import filter_names

        names = filter_names()
        if not isinstance(value, str) or value not in names:
            shown = repr(value) if len(repr(value)) <= 40 else repr(value)[:40] + "..."
            raise ValueError(f"must be one of {_one_of(names)}, got {shown}")
        return value


def _registered_criterion(value: object, *uses: str) -> str:
    """A planner criterion that applies to one of ``uses`` (the registry,
    activetrack.planning.criteria, decides: a registered criterion is accepted at once)."""
    from activetrack.planning.criteria import criterion_names

    names = criterion_names(*uses)
    if not isinstance(value, str) or value not in names:
        raise ValueError(f"must be one of {_one_of(names)}")
    return value


class SelectionConfig(_Strict):
    """Sensor selection (Ramdaras eq. 27): which sensors measure at each epoch."""

    enabled: bool = False
    strategy: Literal["mre", "random", "fixed", "trace"] = "mre"
    criterion: str = "det_pos"  # a criterion for MRE selection (planning.criteria)
    fixed_sensor: str | None = None
    count: SensorCount = 1

    @field_validator("criterion", mode="before")
    @classmethod
    def _criterion(cls, value: object) -> str:
        return _registered_criterion(value, "selection")


class CautiousConfig(_Strict):
    """Beta-cautious greedy localisation (Vander Hook et al., Algorithm 1)."""

    beta: Annotated[float, Field(gt=0, lt=1)] = 0.1
    c_d: Annotated[float, Field(gt=0, lt=1)] = 0.1  # reduce both standard deviations by c_d
    t_m: Dwell = 60.0  # s stopped for each measurement
    r_min: RangeM = 1.0  # m, smallest standoff
    tail: Literal["two_sided", "one_sided"] = "two_sided"
    max_measurements: Measurements | None = None


class PlannerConfig(_Strict):
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
    mc_samples: Samples = 1000
    max_sensor_iterations: SensorIterations = 10
    selection: SelectionConfig = SelectionConfig()
    cautious: CautiousConfig = CautiousConfig()
    # Multi-target scenarios: costs over tracks, beam assignment.
    targets: MultiTargetPlanConfig = MultiTargetPlanConfig()

    @field_validator("criterion", mode="before")
    @classmethod
    def _criterion(cls, value: object) -> str:
        return _registered_criterion(value, "pcrlb", "positioning")

    @field_validator("horizon", mode="before")
    @classmethod
    def _horizon(cls, value: object) -> int:
        """R of the receding horizon (1: single-step, eq. 11; 2: two-step DP, eq. 13-15; R:
        eq. 16, the DP nested R deep or evolution): an integer, neither a bool nor a fraction."""
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= MAX_HORIZON:
            raise ValueError(
                f"must be an integer in [1, {MAX_HORIZON}] (the planning horizon R: 1 "
                f"single-step, 2 two-step, 3 three-step, ...), got {value!r}"
            )
        return value


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


# --- the whole scenario ------------------------------------------------------------------------


class GraphConfig(_Strict):
    """How the ROS graph runner treats node processes (``activetrack run --processes``).

    A restartable node whose process dies is started again (at most ``max_restarts`` times);
    the death of any other node fails the run. Only the planner can be restarted: it keeps no
    state a new one could not rebuild from the latched track and platform states, whereas a
    restarted tracker or simulator would lose the run."""

    restartable: list[Literal["planner"]] = ["planner"]
    max_restarts: Annotated[int, Field(ge=0, le=10)] = 3


class Scenario(_Strict):
    name: str
    description: str = Field(default="", max_length=MAX_DESCRIPTION_LENGTH)
    # Python modules imported before the rest of the file is validated (they register sensor
    # kinds, filters, criteria): scenarios.plugins. A file naming plugins runs their code.
    plugins: list[str] = Field(default=[], max_length=MAX_PLUGINS)
    seed: Seed = 0
    dt: Dt  # s between measurement / decision epochs (T)
    steps: Steps  # epochs k = 1..steps
    # One target (the papers), or a targets: list for a multi-target scenario, whose first
    # entry then also stands as ``target`` (its motion model is every target's).
    target: TargetConfig
    targets: list[TargetConfig] | None = Field(default=None, min_length=1, max_length=MAX_TARGETS)
    platforms: list[PlatformConfig] = Field(min_length=1, max_length=MAX_PLATFORMS)
    tracker: TrackerConfig = TrackerConfig()
    planner: PlannerConfig = PlannerConfig()
    evaluation: EvaluationConfig = EvaluationConfig()
    graph: GraphConfig = GraphConfig()

    @model_validator(mode="before")
    @classmethod
    def _first_target(cls, data: Any) -> Any:
        """``targets:`` without ``target:``: the first target stands as ``target``."""
        targets = data.get("targets") if isinstance(data, dict) else None
        if isinstance(targets, list) and targets and "target" not in data:
            return {**data, "target": targets[0]}
        return data

    @field_validator("name")
    @classmethod
    def _name(cls, value):
        return _identifier("the name (it names the run folder)", value, MAX_NAME_LENGTH)

    @field_validator("plugins")
    @classmethod
    def _plugins(cls, value: list[str]) -> list[str]:
        return check_plugin_names(value)  # names only: scenarios.load imports them

    @field_validator("platforms")
    @classmethod
    def _unique_ids(cls, platforms):
        ids = [p.id for p in platforms]
        sensor_ids = [s.id for p in platforms for s in p.sensors]
        for what, values in (("platform", ids), ("sensor", sensor_ids)):
            dupes = sorted({v for v in values if values.count(v) > 1})
            if dupes:
                raise ValueError(f"{what} ids must be unique, repeated: {dupes}")
        if len(sensor_ids) > MAX_SENSORS:
            raise ValueError(
                f"at most {MAX_SENSORS} sensors in total (activetrack.limits), "
                f"got {len(sensor_ids)}"
            )
        return platforms

    @model_validator(mode="after")
    def _cross_field_rules(self):
        """Rules across sections, each one the cores would otherwise break on when built or
        in the first epochs. All violations are reported, one ``field: message`` per line."""
        problems = _cross_field_problems(self)
        if problems:
            raise ValueError("\n".join(f"{field}: {message}" for field, message in problems))
        return self

    @property
    def duration(self) -> float:
        return self.dt * self.steps

    @property
    def multi_target(self) -> bool:
        """Whether this is a multi-target scenario (a ``targets:`` list)."""
        return self.targets is not None


def _cross_field_problems(s: Scenario) -> list[tuple[str, str]]:
    """``(field, message)`` for every violated cross-field rule (empty: none)."""
    out = []
    if s.dt * s.steps > MAX_DURATION:
        out.append(
            (
                "steps",
                f"dt * steps must be <= {MAX_DURATION:g} s (ROS stamps hold int32 seconds), "
                f"got {s.dt:g} * {s.steps} = {s.dt * s.steps:.3g} s",
            )
        )
    target_model = s.target.motion.model
    # The filter starts from the target's prior, so it must estimate the same state.
    tracker_model = s.tracker.motion.model if s.tracker.motion is not None else target_model
    if MOTION_STATE[tracker_model] != MOTION_STATE[target_model]:
        same = [m for m, names in MOTION_STATE.items() if names == MOTION_STATE[target_model]]
        out.append(
            (
                "tracker.motion.model",
                f"must estimate the target's state {MOTION_STATE[target_model]} (the prior is "
                f"given in it): one of {same} for target.motion.model {target_model!r}, "
                f"got {tracker_model!r}",
            )
        )
    # Range 0 at epoch 0: bearings (and their Jacobians in the EKF and the MRE) are undefined.
    starts = [("target.prior.mean", s.target.prior.mean)]
    if s.target.initial_state is not None:
        starts.append(("target.initial_state", s.target.initial_state))
    for i, p in enumerate(s.platforms):
        blind = [sensor.id for sensor in p.sensors if sensor.r_min == 0.0]
        here = (p.initial_state[0], p.initial_state[2])
        for label, state in starts:
            if blind and _position(state, target_model) == here:
                out.append(
                    (
                        f"platforms.{i}.initial_state",
                        f"the platform starts on the target's position ({label}), where "
                        f"bearings are undefined (range 0): move it, or give its sensors "
                        f"{blind} an r_min > 0",
                    )
                )
    out += multitarget_problems(s)
    if s.targets is not None:
        if s.target != s.targets[0]:
            out.append(("target", "give target or targets, not both"))
    if s.planner.enabled:
        out += _planner_problems(s)
    return out


def _planner_problems(s: Scenario) -> list[tuple[str, str]]:
    cfg = s.planner
    sel = cfg.selection
    out = []
    robots = [(i, p) for i, p in enumerate(s.platforms) if p.controllable]
    target_model = s.target.motion.model
    if cfg.search == "cautious":
        out += _cautious_problems(s, robots)
        uses_track = True
    else:
        out += _steering_problems(s, robots)
        uses_track = (bool(robots) or sel.enabled) and cfg.mode == "renewal"
    if sel.enabled:
        out += _selection_problems(s)
    # Criteria of the MRE (e.g. Ramdaras eq. 25-26) evaluated at the predicted target state.
    criteria = []
    if sel.enabled and cfg.search != "cautious":
        criteria.append(("planner.selection.criterion", sel.criterion))
    if cfg.cost == "mre" and robots and cfg.search != "cautious":
        criteria.append(("planner.criterion", cfg.criterion))
    if criteria and target_model in PV_MODELS:
        out += _criterion_problems(s, criteria)
    particles = _particle_based(s.tracker.filter)
    if uses_track and particles and s.tracker.particles < MIN_PARTICLES_FOR_PLANNING:
        out.append(
            (
                "tracker.particles",
                f"must be >= {MIN_PARTICLES_FOR_PLANNING} with filter {s.tracker.filter!r} "
                f"when the planner works from the track (its covariance must stay "
                f"invertible), got {s.tracker.particles}",
            )
        )
    return out


def _steering_problems(
    s: Scenario, robots: list[tuple[int, PlatformConfig]]
) -> list[tuple[str, str]]:
    """PCRLB planning or MRE positioning of the controllable platforms (not cautious)."""
    from activetrack.planning.criteria import PCRLB, POSITIONING, criterion_names
    from activetrack.planning.selection import POSITIONING_SEARCHES

    cfg = s.planner
    target_model = s.target.motion.model
    out = []
    if cfg.cost == "mre" and cfg.search not in POSITIONING_SEARCHES:
        out.append(
            (
                "planner.search",
                f"must be one of {POSITIONING_SEARCHES} with cost 'mre', got {cfg.search!r}",
            )
        )
    positioning = criterion_names(POSITIONING)
    if cfg.cost == "mre" and robots and cfg.criterion not in positioning:
        out.append(
            (
                "planner.criterion",
                f"must be one of {positioning} with cost 'mre', got {cfg.criterion!r}",
            )
        )
    if cfg.cost == "mre" and cfg.horizon != 1 and cfg.search in POSITIONING_SEARCHES:
        # Multi-step positioning nests one search per leg (planning.selection.plan_positions):
        # per_stage^R evaluations, per_call^R candidate covariances (4 x 4) scored together.
        per_stage, per_call = _search_size(cfg)
        R = cfg.horizon
        if per_stage**R > MAX_SEARCH_EVALUATIONS or 16 * per_call**R > MAX_PLANNER_BATCH:
            out.append(
                (
                    "planner.horizon",
                    f"search {cfg.search!r} with cost 'mre' and horizon {R} costs "
                    f"{per_stage}^{R} = {float(per_stage**R):.3g} cost evaluations per "
                    f"platform and decision, {per_call}^{R} covariances scored together; at "
                    f"most {MAX_SEARCH_EVALUATIONS:.0e} and {MAX_PLANNER_BATCH // 16:.3g} "
                    f"(activetrack.limits): lower the horizon or the search's size",
                )
            )
    if (robots or cfg.selection.enabled) and target_model not in PV_MODELS:
        out.append(
            (
                "target.motion.model",
                f"planning and sensor selection need linear pv dynamics, one of {PV_MODELS}, "
                f"got {target_model!r} (or set planner.enabled: false)",
            )
        )
    if robots and cfg.cost == "pcrlb":
        out += _pcrlb_problems(s, robots, criterion_names(PCRLB))
    return out


def _selection_problems(s: Scenario) -> list[tuple[str, str]]:
    """Sensor selection (Ramdaras eq. 27) among the scenario's sensors."""
    sel = s.planner.selection
    sensor_ids = [sensor.id for p in s.platforms for sensor in p.sensors]
    out = []
    if sel.count > len(sensor_ids):
        out.append(
            (
                "planner.selection.count",
                f"must be <= {len(sensor_ids)} (the number of sensors), got {sel.count}",
            )
        )
    if sel.strategy == "fixed":
        if sel.fixed_sensor not in sensor_ids:
            out.append(
                (
                    "planner.selection.fixed_sensor",
                    f"must be one of {sensor_ids} with strategy 'fixed', got {sel.fixed_sensor!r}",
                )
            )
        if sel.count != 1:
            out.append(
                (
                    "planner.selection.count",
                    f"must be 1 with strategy 'fixed', got {sel.count}",
                )
            )
    return out


def _cautious_problems(
    s: Scenario, robots: list[tuple[int, PlatformConfig]]
) -> list[tuple[str, str]]:
    """Vander Hook's beta-cautious planner (closed_loop.cautious, planning.cautious)."""
    cfg = s.planner
    c = cfg.cautious
    out = []
    names = [p.id for _, p in robots]
    if len(robots) != 1:
        out.append(
            (
                "planner.search",
                f"'cautious' needs exactly one controllable platform (the robot), got "
                f"{len(robots)}: {names}",
            )
        )
    if cfg.cost != "pcrlb":
        out.append(("planner.cost", "must be left at 'pcrlb' with search 'cautious', got 'mre'"))
    if cfg.horizon != 1:
        out.append(
            (
                "planner.horizon",
                f"must be 1 with search 'cautious' (Algorithm 1 is greedy), got {cfg.horizon}",
            )
        )
    if cfg.mode != "renewal":
        out.append(
            (
                "planner.mode",
                "must be 'renewal' with search 'cautious' (it plans from the track), "
                f"got {cfg.mode!r}",
            )
        )
    if cfg.selection.enabled:
        out.append(
            (
                "planner.selection.enabled",
                "sensor selection is not available with search 'cautious'",
            )
        )
    if s.target.motion.model not in PV_MODELS:
        out.append(
            (
                "target.motion.model",
                f"search 'cautious' needs a pv motion model, one of {PV_MODELS}, "
                f"got {s.target.motion.model!r}",
            )
        )
    if c.tail == "one_sided" and c.beta > 0.5:
        out.append(
            ("planner.cautious.beta", f"must be in (0, 0.5] with tail 'one_sided', got {c.beta}")
        )
        return out
    if len(robots) == 1:
        out += _cautious_robot_problems(c, *robots[0])
    return out


def _cautious_robot_problems(
    c: CautiousConfig, i: int, robot: PlatformConfig
) -> list[tuple[str, str]]:
    """The robot's one bearing sensor and the beta-cautious strategy's existence for it."""
    from activetrack.planning.cautious import caution_gamma, sigma_beta

    out = []
    kinds = [sensor.kind for sensor in robot.sensors]
    if len(kinds) != 1 or kinds[0] not in BEARING_KINDS:
        out.append(
            (
                f"platforms.{i}.sensors",
                f"search 'cautious' needs exactly one sensor of kind {BEARING_KINDS} on the "
                f"robot, got {kinds}",
            )
        )
        return out
    sigma = robot.sensors[0].sigma
    sb = sigma_beta(c.beta, c.tail)
    if not sb > sigma:
        out.append(
            (
                f"platforms.{i}.sensors.0.sigma",
                f"must be < sigma_beta(beta={c.beta}, {c.tail}) = {sb:.6g} rad for a "
                f"beta-cautious strategy to exist (Vander Hook sec. III), got {sigma}",
            )
        )
    elif math.isinf(caution_gamma(c.beta, sigma, c.tail)) and c.r_min <= 0.0:
        out.append(
            (
                "planner.cautious.r_min",
                "must be > 0 when sigma_beta is infinite (tail 'one_sided', beta 0.5)",
            )
        )
    return out


def _pcrlb_problems(
    s: Scenario, robots: list[tuple[int, PlatformConfig]], criteria: tuple[str, ...]
) -> list[tuple[str, str]]:
    """PCRLB manoeuvre planning (planning.planner, planning.horizons)."""
    cfg = s.planner
    out = []
    if cfg.criterion not in criteria:
        out.append(
            (
                "planner.criterion",
                f"must be one of {criteria} with cost 'pcrlb', got {cfg.criterion!r}",
            )
        )
    for i, p in robots:
        if math.hypot(p.initial_state[1], p.initial_state[3]) == 0.0:
            out.append(
                (
                    f"platforms.{i}.initial_state",
                    "a platform steered by PCRLB planning needs a nonzero initial velocity "
                    "(its heading)",
                )
            )
        v_min = p.limits.v_min if p.limits is not None else 0.0  # limits: given when controllable
        if v_min <= 0.0:
            out.append(
                (
                    f"platforms.{i}.limits.v_min",
                    "must be > 0 for a platform steered by PCRLB planning (at rest it would "
                    f"have no heading), got {v_min}",
                )
            )
    R = cfg.horizon
    if cfg.search == "evolution":
        batch = _EVOLUTION_POPSIZE * 2 * R
    else:
        per_stage, per_call = _search_size(cfg)
        if per_stage**R > MAX_SEARCH_EVALUATIONS:
            out.append(
                (
                    "planner.horizon",
                    f"search {cfg.search!r} with horizon {R} costs {per_stage}^{R} = "
                    f"{float(per_stage**R):.3g} cost evaluations per platform and decision; "
                    f"at most {MAX_SEARCH_EVALUATIONS:.0e} (activetrack.limits): lower the "
                    f"horizon or the search's size",
                )
            )
            return out
        batch = per_call**R
    pf_renewal = _particle_based(s.tracker.filter) and cfg.mode == "renewal"
    samples = min(s.tracker.planner_samples, s.tracker.particles) if pf_renewal else cfg.mc_samples
    field = "tracker.planner_samples" if pf_renewal else "planner.mc_samples"
    if batch * samples > MAX_PLANNER_BATCH:
        out.append(
            (
                field,
                f"{samples} samples x {batch} candidates scored together (search "
                f"{cfg.search!r}, horizon {R}) exceeds {MAX_PLANNER_BATCH:.1e} "
                f"(about 1 GB, activetrack.limits): use at most {MAX_PLANNER_BATCH // batch} "
                f"samples",
            )
        )
    return out


def _criterion_problems(s: Scenario, criteria: list[tuple[str, str]]) -> list[tuple[str, str]]:
    """Criteria undefined at the predicted target state (the registry's ``state_problem``:
    heading of a target at rest; range, Doppler and bearing taken from the origin, Ramdaras
    eq. 26, with the target there). Checked at the first prediction."""
    from activetrack.models.base import as_linear
    from activetrack.planning.criteria import get_criterion
    from activetrack.scenarios.build import build_motion_model

    F = as_linear(build_motion_model(s.target.motion)).transition_matrix(s.dt)
    x = F @ np.asarray(s.target.prior.mean, dtype=float)
    out = []
    for field, name in criteria:
        problem = get_criterion(name).state_problem
        reason = problem(x) if problem is not None else None
        if reason:
            out.append((field, f"{name!r} {reason} (target.prior.mean)"))
    return out
