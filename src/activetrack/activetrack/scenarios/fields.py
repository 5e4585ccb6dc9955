"""The field types of scenario files and the base of every sensor entry.

The lowest layer of the scenario package: bounded numbers (:mod:`activetrack.limits`),
identifiers, the strict base model, the state layout of each motion model and
:class:`SensorConfigBase`. It imports no component, so the schema, the sensor-kind registry and
a plugin's sensor config can all build on it. Units: metres, seconds, radians.
"""

from __future__ import annotations

import math
import re
from typing import TYPE_CHECKING, Annotated, Any, Self, get_args

from pydantic import AfterValidator, BaseModel, ConfigDict, Field, model_validator
from pydantic.fields import FieldInfo

from activetrack import limits


def float_range(
    lo: float | None = None,
    hi: float | None = None,
    *,
    gt: float | None = None,
    lt: float | None = None,
) -> Any:
    """The bounds of a finite float field (``Annotated[float, float_range(...)]``)."""
    return Field(ge=lo, le=hi, gt=gt, lt=lt, allow_inf_nan=False)


FiniteFloat = Annotated[float, float_range()]
# Magnitudes (activetrack.limits).
Speed = Annotated[float, float_range(0, limits.MAX_SPEED)]  # m/s
PositiveSpeed = Annotated[float, float_range(gt=0, hi=limits.MAX_SPEED)]
Acceleration = Annotated[float, float_range(0, limits.MAX_ACCELERATION)]  # m/s^2
NoisePsd = Annotated[float, float_range(0, limits.MAX_Q)]  # m^2/s^3
TurnRate = Annotated[float, float_range(-limits.MAX_TURN_RATE, limits.MAX_TURN_RATE)]  # rad/s
TurnRateStd = Annotated[float, float_range(0, limits.MAX_TURN_RATE)]
PositiveTurnRate = Annotated[float, float_range(gt=0, hi=limits.MAX_TURN_RATE)]
# rad; a turn beyond pi is one the other way
HeadingChange = Annotated[float, float_range(gt=0, hi=math.pi)]
RangeM = Annotated[float, float_range(0, limits.MAX_RANGE)]  # m
BearingSigma = Annotated[float, float_range(limits.MIN_SIGMA, limits.MAX_BEARING_SIGMA)]  # rad
RangeSigma = Annotated[float, float_range(limits.MIN_SIGMA, limits.MAX_RANGE)]  # m
RateSigma = Annotated[float, float_range(limits.MIN_SIGMA, limits.MAX_SPEED)]  # m/s
Variance = Annotated[float, float_range(0, limits.MAX_PRIOR_VARIANCE)]
Covariance = Annotated[float, float_range(-limits.MAX_PRIOR_VARIANCE, limits.MAX_PRIOR_VARIANCE)]
Dt = Annotated[float, float_range(limits.MIN_DT, limits.MAX_DT)]  # s
Dwell = Annotated[float, float_range(0, limits.MAX_DWELL)]  # s
Roughening = Annotated[float, float_range(0, limits.MAX_ROUGHENING)]
Particles = Annotated[int, Field(ge=1, le=limits.MAX_PARTICLES)]
Samples = Annotated[int, Field(ge=1, le=limits.MAX_SAMPLES)]
SensorCount = Annotated[int, Field(ge=1, le=limits.MAX_SENSORS)]
Horizon = Annotated[int, Field(ge=1, le=limits.MAX_HORIZON)]
GridSize = Annotated[int, Field(ge=3, le=limits.MAX_GRID_SIZE)]
Divisions = Annotated[int, Field(ge=1, le=limits.MAX_QUADRANT_DIVISIONS)]
SectorLevels = Annotated[int, Field(ge=1, le=limits.MAX_SECTOR_LEVELS)]
SensorIterations = Annotated[int, Field(ge=1, le=limits.MAX_SENSOR_ITERATIONS)]
Measurements = Annotated[int, Field(ge=1, le=limits.MAX_MEASUREMENTS)]
Seed = Annotated[int, Field(ge=0, le=limits.MAX_SEED)]
Steps = Annotated[int, Field(ge=1, le=limits.MAX_STEPS)]


# Scenario names become folder names (runs/<name>-<time>), ids go into messages and plots.
_IDENTIFIER = re.compile(r"[A-Za-z0-9_-][A-Za-z0-9_.-]*")


def check_identifier(what: str, value: str, max_length: int) -> str:
    """``value`` if it is a name safe for folders and messages, else a ValueError."""
    if not (len(value) <= max_length and _IDENTIFIER.fullmatch(value)):
        shown = value if len(value) <= 40 else value[:40] + "..."
        raise ValueError(
            f"{what} must be 1-{max_length} characters of letters, digits, '_', '-' and '.', "
            f"not starting with '.', got {shown!r}"
        )
    return value


def shown(value: object, limit: int = 60) -> str:
    """``repr(value)`` for an error message, cut to ``limit`` characters ("..." after)."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit] + "..."


def identifier(what: str, max_length: int = limits.MAX_ID_LENGTH) -> Any:
    """A name checked by :func:`check_identifier` (``Annotated[str, identifier(what)]``)."""
    return AfterValidator(lambda value: check_identifier(what, value, max_length))


class Strict(BaseModel):
    """A section of a scenario file: unknown keys are errors, values are frozen, and a
    boolean is no number (pydantic would read ``dt: true`` as 1.0)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    @model_validator(mode="before")
    @classmethod
    def _no_booleans_as_numbers(cls, data: Any) -> Any:
        if not isinstance(data, dict):
            return data
        problems = [
            f"{name}: must be {_allowed(field)}, not a boolean (got {shown(value)})"
            for name, value in data.items()
            if (field := cls.model_fields.get(name)) is not None
            and _holds_bool(value)
            and not _mentions_bool(field.annotation)
        ]
        if problems:
            raise ValueError("\n".join(problems))
        return data


def _holds_bool(value: Any) -> bool:
    """A bool, or a list (of lists) holding one."""
    if isinstance(value, list | tuple):
        return any(_holds_bool(v) for v in value)
    return isinstance(value, bool)


def _mentions_bool(annotation: Any) -> bool:
    """The field's type takes booleans (bool, StrictBool, bool | None, ...)."""
    return annotation is bool or any(_mentions_bool(a) for a in get_args(annotation))


def _allowed(field: FieldInfo) -> str:
    """What a field that is not boolean takes, e.g. "a number in [0.001, 10000]"."""
    bounds = {
        k: getattr(m, k) for m in field.metadata for k in ("ge", "gt", "le", "lt")
        if getattr(m, k, None) is not None
    }  # fmt: skip
    annotation = str(field.annotation)
    what = "numbers" if "list" in annotation else "an integer" if field.annotation is int else (
        "a number"
    )  # fmt: skip
    if not bounds:
        return what
    lo = f"[{bounds['ge']:g}" if "ge" in bounds else f"({bounds.get('gt', -math.inf):g}"
    hi = f"{bounds['le']:g}]" if "le" in bounds else f"{bounds.get('lt', math.inf):g})"
    return f"{what} in {lo}, {hi}"


# --- states ------------------------------------------------------------------------------------

PV = ("x", "xdot", "y", "ydot")
# State of each motion model (the cores' ``state_names``): the layout of a prior's mean and of
# an initial state in the file.
MOTION_STATE = {
    "ncv": PV,
    "ncv_discrete": PV,
    "constant_turn": PV,
    "circular": ("psi", "px", "py", "omega", "v"),
    "circular_known_omega": ("psi", "px", "py", "v"),
}
# Linear dynamics on a pv state: what PCRLB / MRE planning and the cautious planner need.
PV_MODELS = ("ncv", "ncv_discrete", "constant_turn")
STATE_BOUND = (
    dict.fromkeys(("x", "y", "px", "py"), limits.MAX_POSITION)
    | dict.fromkeys(("xdot", "ydot", "v"), limits.MAX_SPEED)
    | {"psi": limits.MAX_ANGLE, "omega": limits.MAX_TURN_RATE}
)


def check_state(values: Any, names: tuple[str, ...]) -> None:
    """Each entry within the bound of its state component (``STATE_BOUND``)."""
    for i, (value, name) in enumerate(zip(values, names, strict=False)):
        bound = STATE_BOUND[name]
        if abs(value) > bound:
            raise ValueError(
                f"entry {i} ({name}) must be within +-{bound:g} (activetrack.limits), got {value!r}"
            )


def position_of(values: Any, model: str) -> tuple[float, float]:
    """The (x, y) position in a state of motion model ``model``."""
    names = MOTION_STATE[model]
    ix = names.index("x") if "x" in names else names.index("px")
    iy = names.index("y") if "y" in names else names.index("py")
    return float(values[ix]), float(values[iy])


# --- sensors -----------------------------------------------------------------------------------


class SensorConfigBase(Strict):
    """Fields of every sensor kind: its id and detection model (pd inside [r_min, r_max],
    Hernandez sec. 2.3, Ramdaras eq. 14-22). A kind's config derives from this, adds
    ``kind: Literal["<kind>"]`` and its own fields, and is registered with its sensor class
    (:func:`activetrack.scenarios.registry.register_sensor`)."""

    id: Annotated[str, identifier("a sensor id")]
    pd: Annotated[float, Field(gt=0, le=1)] = 1.0
    r_min: RangeM = 0.0
    r_max: Annotated[float, Field(gt=0)] = math.inf  # inf: no maximum range
    # Multi-target scenarios only (scenarios.rules): Poisson false alarms per unit of z (per
    # rad; per m rad for range-bearing) over the field of view, which is a bearing sector
    # fov_width wide centred fov_centre off the platform's heading (None: all around), or a
    # steerable beam beam_width wide the planner points at one track per epoch.
    clutter_density: Annotated[float, float_range(0, limits.MAX_CLUTTER_DENSITY)] = 0.0
    fov_centre: Annotated[float, float_range(-math.pi, math.pi)] = 0.0
    fov_width: Annotated[float, float_range(gt=0, hi=2 * math.pi)] | None = None
    beam_width: Annotated[float, float_range(gt=0, hi=2 * math.pi)] | None = None
    if TYPE_CHECKING:
        kind: str  # a field of every subclass, as Literal["<kind>"]

        # The kind's own fields (sigma, sigma_r, ...): the registry decides which at run time.
        def __getattr__(self, name: str) -> Any: ...

    @model_validator(mode="after")
    def _ranges(self) -> Self:
        if math.isfinite(self.r_max) and self.r_max > limits.MAX_RANGE:
            raise ValueError(
                f"r_max: must be <= {limits.MAX_RANGE:g} m or .inf (no maximum), got {self.r_max!r}"
            )
        if not self.r_min < self.r_max:
            raise ValueError(f"r_max: must be greater than r_min ({self.r_min}), got {self.r_max}")
        return self
