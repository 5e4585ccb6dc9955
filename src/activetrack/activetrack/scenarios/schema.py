"""The scenario file schema (YAML), validated on load with pydantic.

One schema for the batch loop, the experiment runners and the ROS nodes. Units: metres,
seconds, radians. States are pv vectors (x, xdot, y, ydot) unless the motion model says
otherwise.

Unknown keys are errors (a typo must not silently fall back to a default).
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator, model_validator

PositiveFloat = Annotated[float, Field(gt=0, allow_inf_nan=False)]
NonNegFloat = Annotated[float, Field(ge=0, allow_inf_nan=False)]
FiniteFloat = Annotated[float, Field(allow_inf_nan=False)]


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


# --- motion models -----------------------------------------------------------------------------


class NcvMotion(_Strict):
    """Continuous white-noise acceleration, PSD q (Hernandez sec. 5.1, l)."""

    model: Literal["ncv"]
    q: NonNegFloat


class NcvDiscreteMotion(_Strict):
    """Discrete noise gain G with sigma_x, sigma_y (Ramdaras eq. 3-4)."""

    model: Literal["ncv_discrete"]
    sigma_x: NonNegFloat
    sigma_y: NonNegFloat


class ConstantTurnMotion(_Strict):
    """Constant turn with known rate omega (Valverde eq. 30-37)."""

    model: Literal["constant_turn"]
    omega: FiniteFloat
    q: NonNegFloat


class CircularMotionConfig(_Strict):
    """Circular motion, state (psi, px, py, omega, v) (Valverde eq. 15-28)."""

    model: Literal["circular"]
    sigma_omega: NonNegFloat
    sigma_v: NonNegFloat


class CircularKnownOmegaMotion(_Strict):
    model: Literal["circular_known_omega"]
    omega: FiniteFloat
    sigma_v: NonNegFloat


MotionConfig = Annotated[
    NcvMotion
    | NcvDiscreteMotion
    | ConstantTurnMotion
    | CircularMotionConfig
    | CircularKnownOmegaMotion,
    Field(discriminator="model"),
]

MOTION_STATE_DIM = {
    "ncv": 4,
    "ncv_discrete": 4,
    "constant_turn": 4,
    "circular": 5,
    "circular_known_omega": 4,
}

# --- sensors -----------------------------------------------------------------------------------


class _SensorCommon(_Strict):
    id: str = Field(min_length=1)
    pd: Annotated[float, Field(gt=0, le=1)] = 1.0
    r_min: NonNegFloat = 0.0
    r_max: Annotated[float, Field(gt=0)] = math.inf

    @model_validator(mode="after")
    def _ranges(self):
        if not self.r_min < self.r_max:
            raise ValueError(f"r_max ({self.r_max}) must be greater than r_min ({self.r_min})")
        return self


class BearingSensorConfig(_SensorCommon):
    kind: Literal["bearing", "ambiguous_bearing"]
    sigma: PositiveFloat  # rad


class RangeBearingSensorConfig(_SensorCommon):
    kind: Literal["range_bearing"]
    sigma_r: PositiveFloat  # m
    sigma_b: PositiveFloat  # rad


class RangeRateBearingSensorConfig(_SensorCommon):
    kind: Literal["range_rate_bearing"]
    sigma_r: PositiveFloat  # m
    sigma_rr: PositiveFloat  # m/s
    sigma_b: PositiveFloat  # rad


SensorConfig = Annotated[
    BearingSensorConfig | RangeBearingSensorConfig | RangeRateBearingSensorConfig,
    Field(discriminator="kind"),
]

# --- platforms ---------------------------------------------------------------------------------


class ManoeuvreLimits(_Strict):
    """Per decision epoch: heading change within +-dpsi_max, speed change within +-dv_max and
    speed within [v_min, v_max] (Hernandez sec. 3.3.1, 5.1). Ramdaras' limits (sec. 5: max
    longitudinal acceleration a_max, heading rate psi_rate_max) map to dv_max = a_max T and
    dpsi_max = psi_rate_max T; give either pair."""

    dpsi_max: PositiveFloat | None = None
    dv_max: NonNegFloat | None = None
    a_max: NonNegFloat | None = None
    psi_rate_max: PositiveFloat | None = None
    v_min: NonNegFloat = 0.0
    v_max: PositiveFloat

    @model_validator(mode="after")
    def _one_pair(self):
        hernandez = self.dpsi_max is not None and self.dv_max is not None
        ramdaras = self.a_max is not None and self.psi_rate_max is not None
        if hernandez == ramdaras:
            raise ValueError(
                "give exactly one of the pairs (dpsi_max, dv_max) or (a_max, psi_rate_max)"
            )
        if not self.v_min <= self.v_max:
            raise ValueError(f"v_min ({self.v_min}) must not exceed v_max ({self.v_max})")
        return self

    def per_epoch(self, dt: float) -> tuple[float, float]:
        """(dpsi_max, dv_max) for one decision interval of dt seconds."""
        if self.dpsi_max is not None:
            return self.dpsi_max, self.dv_max
        return self.psi_rate_max * dt, self.a_max * dt


class PlatformConfig(_Strict):
    id: str = Field(min_length=1)
    initial_state: list[FiniteFloat] = Field(min_length=4, max_length=4)  # pv
    controllable: bool = False
    limits: ManoeuvreLimits | None = None
    sensors: list[SensorConfig] = Field(min_length=1)

    @model_validator(mode="after")
    def _limits_if_controllable(self):
        if self.controllable and self.limits is None:
            raise ValueError("a controllable platform needs limits")
        return self


# --- target ------------------------------------------------------------------------------------


class PriorConfig(_Strict):
    """Gaussian prior of the target state: mean and either cov (full) or std (diagonal)."""

    mean: list[FiniteFloat]
    cov: list[list[FiniteFloat]] | None = None
    var: list[NonNegFloat] | None = None

    @model_validator(mode="after")
    def _one_cov(self):
        if (self.cov is None) == (self.var is None):
            raise ValueError("give exactly one of cov (full matrix) or var (diagonal)")
        P = self.covariance()
        n = len(self.mean)
        if P.shape != (n, n):
            raise ValueError(f"covariance must be {n}x{n} to match mean, got {P.shape}")
        if not np.allclose(P, P.T) or np.any(np.linalg.eigvalsh(P) <= 0):
            raise ValueError("covariance must be symmetric positive definite")
        return self

    def covariance(self) -> np.ndarray:
        return np.diag(self.var) if self.var is not None else np.array(self.cov, dtype=float)


class TargetConfig(_Strict):
    id: str = "t1"
    motion: MotionConfig
    prior: PriorConfig
    # Truth at k = 0: a fixed state, or drawn from the prior with the simulator's generator.
    initial_state: list[FiniteFloat] | None = None

    @model_validator(mode="after")
    def _dims(self):
        n = MOTION_STATE_DIM[self.motion.model]
        if len(self.prior.mean) != n:
            raise ValueError(f"prior.mean must have {n} entries for motion {self.motion.model}")
        if self.initial_state is not None and len(self.initial_state) != n:
            raise ValueError(f"initial_state must have {n} entries for motion {self.motion.model}")
        return self


# --- tracker and planner -----------------------------------------------------------------------


class TrackerConfig(_Strict):
    filter: Literal["ekf", "pf"] = "pf"
    particles: Annotated[int, Field(ge=1)] = 10000
    resample: Literal["always", "ess"] = "always"
    ess_threshold: Annotated[float, Field(gt=0, le=1)] = 0.5
    roughening: NonNegFloat = 0.0
    min_range: Literal["ignore", "negative"] = "ignore"
    # Motion model the filter assumes; None: the target's own.
    motion: MotionConfig | None = None
    # Equally weighted posterior samples handed to the planner for renewal (PF only).
    planner_samples: Annotated[int, Field(ge=1)] = 1000


class SelectionConfig(_Strict):
    """Sensor selection (Ramdaras eq. 27): which sensors measure at each epoch."""

    enabled: bool = False
    strategy: Literal["mre", "random", "fixed", "trace"] = "mre"
    criterion: Literal["det_pos", "heading", "range", "doppler", "bearing"] = "det_pos"
    fixed_sensor: str | None = None
    count: Annotated[int, Field(ge=1)] = 1


class CautiousConfig(_Strict):
    """Beta-cautious greedy localisation (Vander Hook et al., Algorithm 1)."""

    beta: Annotated[float, Field(gt=0, lt=1)] = 0.1
    c_d: Annotated[float, Field(gt=0, lt=1)] = 0.1  # reduce both standard deviations by c_d
    t_m: NonNegFloat = 60.0  # s stopped for each measurement
    r_min: NonNegFloat = 1.0  # m, smallest standoff
    tail: Literal["two_sided", "one_sided"] = "two_sided"
    max_measurements: Annotated[int, Field(ge=1)] | None = None


class PlannerConfig(_Strict):
    enabled: bool = True
    cost: Literal["pcrlb", "mre"] = "pcrlb"
    criterion: Literal["b_k", "trace", "det_pos", "heading", "range", "doppler", "bearing"] = "b_k"
    horizon: Annotated[int, Field(ge=1, le=10)] = 1
    search: Literal["grid", "quadrant", "sector", "evolution", "cautious"] = "quadrant"
    grid_size: Annotated[int, Field(ge=3)] = 101
    quadrant_divisions: Annotated[int, Field(ge=1)] = 6
    quadrant_patience: Annotated[int, Field(ge=1)] = 6
    sector_levels: Annotated[int, Field(ge=1)] = 3
    mode: Literal["renewal", "open_loop"] = "renewal"
    mc_samples: Annotated[int, Field(ge=1)] = 1000
    max_sensor_iterations: Annotated[int, Field(ge=1)] = 10
    selection: SelectionConfig = SelectionConfig()
    cautious: CautiousConfig = CautiousConfig()


# --- the whole scenario ------------------------------------------------------------------------


class Scenario(_Strict):
    name: str = Field(min_length=1)
    description: str = ""
    seed: Annotated[int, Field(ge=0)] = 0
    dt: PositiveFloat  # s between measurement / decision epochs (T)
    steps: Annotated[int, Field(ge=1)]  # epochs k = 1..steps
    target: TargetConfig
    platforms: list[PlatformConfig] = Field(min_length=1)
    tracker: TrackerConfig = TrackerConfig()
    planner: PlannerConfig = PlannerConfig()

    @field_validator("platforms")
    @classmethod
    def _unique_ids(cls, platforms):
        ids = [p.id for p in platforms]
        sensor_ids = [s.id for p in platforms for s in p.sensors]
        for what, values in (("platform", ids), ("sensor", sensor_ids)):
            dupes = sorted({v for v in values if values.count(v) > 1})
            if dupes:
                raise ValueError(f"{what} ids must be unique, repeated: {dupes}")
        return platforms

    @model_validator(mode="after")
    def _selection_refs(self):
        sel = self.planner.selection
        if sel.enabled and sel.strategy == "fixed":
            ids = [s.id for p in self.platforms for s in p.sensors]
            if sel.fixed_sensor not in ids:
                raise ValueError(
                    f"planner.selection.fixed_sensor must be one of {ids}, got {sel.fixed_sensor!r}"
                )
        return self

    @property
    def duration(self) -> float:
        return self.dt * self.steps
