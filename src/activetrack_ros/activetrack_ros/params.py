"""Node parameters that tell the truth: each declared once, with a descriptor (description,
type, range or allowed values, read-only where a running node cannot apply a change), checked
at start-up (a bad value stops the node with exit 2 before it publishes) and at run time (a
change is applied by the node, or refused with the reason: what ``ros2 param set`` reports).
"""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import dataclass

from rcl_interfaces.msg import (
    FloatingPointRange,
    IntegerRange,
    ParameterDescriptor,
    ParameterType,
    SetParametersResult,
)
from rclpy.exceptions import ParameterException
from rclpy.parameter import Parameter

from activetrack_ros.graph import FIXED_FRAME

_TYPES = {
    bool: ParameterType.PARAMETER_BOOL,
    int: ParameterType.PARAMETER_INTEGER,
    float: ParameterType.PARAMETER_DOUBLE,
    str: ParameterType.PARAMETER_STRING,
}


@dataclass(frozen=True)
class ParamSpec:
    """One node parameter. ``low``/``high``: closed range (numbers); ``choices``: allowed
    strings (a callable for registries that grow, e.g. filter names); ``required``: a string
    that must not stay empty; ``read_only=False``: the node applies run-time changes."""

    name: str
    default: bool | int | float | str
    description: str
    read_only: bool = True
    low: float | None = None
    high: float | None = None
    choices: tuple[str, ...] | Callable[[], tuple[str, ...]] = ()
    required: bool = False
    pattern: str | None = None  # a string's form (regular expression, whole match)

    @property
    def type(self) -> type:
        return type(self.default)

    def allowed(self) -> tuple[str, ...]:
        return tuple(self.choices()) if callable(self.choices) else self.choices

    def descriptor(self) -> ParameterDescriptor:
        d = ParameterDescriptor(
            name=self.name,
            type=_TYPES[self.type],
            description=self.description,
            read_only=self.read_only,
        )
        low, high = self.low, self.high
        if self.type is float and low is not None and high is not None:
            d.floating_point_range = [
                FloatingPointRange(from_value=float(low), to_value=float(high))
            ]
        elif self.type is int and low is not None and high is not None:
            d.integer_range = [IntegerRange(from_value=int(low), to_value=int(high), step=1)]
        allowed = self.allowed()
        if allowed:
            d.additional_constraints = f"one of {list(allowed)}" + (
                "" if self.required else " (or empty)"
            )
        elif self.required:
            d.additional_constraints = "must not be empty"
        if self.pattern:
            d.additional_constraints += f" matching {self.pattern}"
        return d

    def check(self, value) -> str | None:
        """Why ``value`` is not allowed (a sentence naming the parameter), or None."""
        if self.type is float and isinstance(value, int) and not isinstance(value, bool):
            value = float(value)
        if not isinstance(value, self.type) or (self.type is int and isinstance(value, bool)):
            return (
                f"parameter '{self.name}' must be a {self.type.__name__}, got "
                f"{type(value).__name__} {value!r}"
            )
        low = -math.inf if self.low is None else self.low
        high = math.inf if self.high is None else self.high
        if self.type in (int, float) and not (math.isfinite(value) and low <= value <= high):
            return f"parameter '{self.name}' must be in [{self.low}, {self.high}], got {value!r}"
        allowed = self.allowed()
        if self.type is str and allowed and value not in allowed and (value or self.required):
            empty = "" if self.required else " (or empty)"
            return f"parameter '{self.name}' must be one of {list(allowed)}{empty}, got {value!r}"
        if self.type is str and self.required and not value:
            return f"parameter '{self.name}' must not be empty: {self.description}"
        if self.pattern and value and not re.fullmatch(self.pattern, value):
            return f"parameter '{self.name}' must match {self.pattern}, got {value!r}"
        return None


# Parameters every graph node has.
SCENARIO = ParamSpec(
    "scenario", "", "scenario YAML file (checked on load: docs in README)", required=True
)
RUN = ParamSpec(
    "run", -1, "Monte Carlo run index for seeding (-1: the scenario's seed only)",
    low=-1, high=2**31 - 1,
)  # fmt: skip
MODE = ParamSpec(
    "mode", "lockstep",
    "lockstep: epoch k+1 waits for every answer to epoch k (deterministic); free: sim time "
    "runs at 'rate' x wall time",
    choices=("lockstep", "free"), required=True,
)  # fmt: skip
FRAME_ID = ParamSpec(
    "frame_id", FIXED_FRAME,
    "fixed frame of every header and the root of the tf tree (docs/frames.md)",
    required=True, pattern=r"[A-Za-z_][A-Za-z0-9_]*(/[A-Za-z0-9_]+)*",
)  # fmt: skip
COMMON = (SCENARIO, RUN, MODE, FRAME_ID)


def _as_float(p: Parameter, floats) -> Parameter:
    """An integer given for a float parameter (``-p rate:=5``, ``ros2 param set /sim_node rate
    5``) taken as that float, where rclpy would refuse it as the wrong type."""
    if p.name in floats and p.type_ == Parameter.Type.INTEGER:
        return Parameter(p.name, value=float(p.value))
    return p


def declare(node, specs: tuple[ParamSpec, ...]) -> dict:
    """Declare ``specs`` on ``node``; their values, or ValueError naming a bad one's limits."""
    overrides = node._parameter_overrides  # what --ros-args / params files / the caller gave
    floats = {s.name for s in specs if s.type is float}
    values = {}
    for spec in specs:
        if spec.name in overrides:
            overrides[spec.name] = _as_float(overrides[spec.name], floats)
        try:
            value = node.declare_parameter(spec.name, spec.default, spec.descriptor()).value
        except ParameterException as exc:
            given = overrides.get(spec.name)
            problem = spec.check(given.value) if given is not None else None
            raise ValueError(problem or f"parameter '{spec.name}': {exc}") from None
        problem = spec.check(value)
        if problem:
            raise ValueError(problem)
        values[spec.name] = value
    return values


def warn_unknown(node) -> None:
    """Log the overrides (params file, ``-p``) that name no parameter of the node: a params
    file may address several nodes at once (``/**``), so this warns and does not fail."""
    declared = set(node._parameters)
    unknown = sorted(n for n in node._parameter_overrides if n not in declared)
    if unknown:
        node.get_logger().warning(
            f"parameters {unknown} are not parameters of {node.get_name()} (ignored); it has "
            f"{sorted(declared)}"
        )


# rclpy declares use_sim_time on every node (False, undescribed, writable); on sim time a
# graph node's timers would never fire while lockstep waits (true froze a free run's clock).
USE_SIM_TIME = "use_sim_time"
USE_SIM_TIME_DESCRIPTION = (
    "fixed false: the node stamps messages with simulated time itself and its timers keep "
    "wall time (/clock stands still while lockstep waits); tools that follow the run (RViz, "
    "a recorder) take use_sim_time:=true"
)


def fix_use_sim_time(node) -> None:
    """Make ``use_sim_time`` read-only and described on a graph node: a change is refused, and
    ``true`` given at start-up (``-p``, a params file's ``/**``) is a ValueError (exit 2)."""
    if node.get_parameter(USE_SIM_TIME).value is not False:
        raise ValueError(
            f"parameter '{USE_SIM_TIME}' must be false for {node.get_name()}: "
            f"{USE_SIM_TIME_DESCRIPTION}"
        )
    node.set_descriptor(
        USE_SIM_TIME,
        ParameterDescriptor(
            type=ParameterType.PARAMETER_BOOL,
            description=USE_SIM_TIME_DESCRIPTION,
            read_only=True,
            additional_constraints="must stay false",
        ),
    )


def on_change(node, specs: tuple[ParamSpec, ...], apply: dict[str, Callable | str]) -> None:
    """Accept run-time changes of the mutable parameters (checked, then ``apply[name](value)``
    after they are set) and refuse every other change with a reason (``apply[name]`` may be
    that reason, for a change the node's present state cannot take; the dict may change while
    the node runs). rclpy refuses read-only ones itself ("Trying to set a read-only
    parameter")."""
    by_name = {s.name: s for s in specs}
    floats = {s.name for s in specs if s.type is float}

    def as_float(params: list[Parameter]) -> list[Parameter]:
        return [_as_float(p, floats) for p in params]

    def refusal(p: Parameter) -> str | None:
        spec = by_name.get(p.name)
        if spec is None:
            return None  # use_sim_time and rclpy's own
        if spec.read_only or p.name not in apply:
            return f"parameter '{p.name}' cannot change while the node runs"
        if isinstance(apply[p.name], str):  # changeable, but not in this node's state
            return apply[p.name]
        return spec.check(p.value)

    def validate(params: list[Parameter]) -> SetParametersResult:
        reasons = [r for r in map(refusal, params) if r]
        return SetParametersResult(successful=not reasons, reason=reasons[0] if reasons else "")

    def applied(params: list[Parameter]) -> None:
        for p in params:
            if p.name in by_name and callable(apply.get(p.name)):
                value = p.value
                apply[p.name](float(value) if by_name[p.name].type is float else value)
                node.get_logger().info(f"parameter '{p.name}' set to {value!r}")

    node.add_pre_set_parameters_callback(as_float)
    node.add_on_set_parameters_callback(validate)
    node.add_post_set_parameters_callback(applied)
