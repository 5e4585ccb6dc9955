"""Sensor kinds that scenario files can name: each registered once, with its class and config
(an example: docs/extending.md).

A kind is the sensor class (contract :class:`activetrack.models.base.SensorModel`; its class
attribute ``kind`` is the name) together with its scenario configuration: a pydantic model
deriving from :class:`activetrack.scenarios.fields.SensorConfigBase` (id, pd, r_min, r_max)
with ``kind: Literal["<kind>"]`` and the sensor's own fields. Once registered, a ``sensors:``
entry of that kind loads (the schema's sensor entries are the discriminated union, on ``kind``,
of the registered configs; an unknown kind's error lists them) and
:func:`activetrack.scenarios.build.build_sensor` makes the sensor: by default
``SensorClass(**fields)`` with every config field but the scene's (``SCENE_FIELDS``), or
``build(config)`` when one is given. The built-in kinds register the same way
(``scenarios.build``). The registry is scenario data: it holds classes and calls, and imports
no component (a sensor class is checked for the members of the contract by name).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Annotated, Any, Literal, Union, get_args, get_origin

from pydantic import BaseModel, Field

from activetrack.scenarios.fields import SensorConfigBase

__all__ = [
    "SensorKind",
    "on_registry_change",
    "register_sensor",
    "registered_kinds",
    "sensor_config_union",
    "sensor_kind",
    "unregister_sensor",
]

_KIND_NAME = re.compile(r"[a-z][a-z0-9_]*")
# What a sensor class must offer (the members of activetrack.models.base.SensorModel that exist
# on the class itself; pd, r_min and r_max are dataclass fields, guaranteed by the config's
# base class).
_CLASS_MEMBERS = (
    "components",
    "R",
    "dim_z",
    "measure",
    "jacobian",
    "residual",
    "in_range",
    "detect",
    "sample",
    "linearize",
    "log_likelihood",
    "log_miss_likelihood",
    "fisher_information",
)


@dataclass(frozen=True)
class SensorKind:
    """One registered kind: its sensor class, its config model and how to build the sensor
    (``build(config)``: a sensor model, contract ``activetrack.models.base.SensorModel``)."""

    kind: str
    sensor_class: type
    config_class: type[BaseModel]
    build: Callable[[Any], Any]


_KINDS: dict[str, SensorKind] = {}
_LISTENERS: list[Callable[[], None]] = []


# Fields of every sensor entry that describe the scene around the sensor (its field of view and
# clutter: models.clutter.ClutteredSensor), not the sensor model's constructor arguments.
SCENE_FIELDS = ("id", "kind", "clutter_density", "fov_centre", "fov_width", "beam_width")


def _default_build(sensor_class: type) -> Callable[[Any], Any]:
    def build(cfg: BaseModel) -> Any:
        fields = {k: getattr(cfg, k) for k in type(cfg).model_fields if k not in SCENE_FIELDS}
        return sensor_class(**fields)

    return build


def _check_config(kind: str, config_class: type) -> None:
    if not (isinstance(config_class, type) and issubclass(config_class, SensorConfigBase)):
        raise ValueError(
            f"config_class must be a subclass of activetrack.scenarios.SensorConfigBase, "
            f"got {config_class!r}"
        )
    field = config_class.model_fields.get("kind")
    tags = get_args(field.annotation) if field is not None else ()
    if field is None or get_origin(field.annotation) is not Literal or tags != (kind,):
        raise ValueError(
            f"config_class {config_class.__name__} must declare kind: Literal[{kind!r}], "
            f"got {field.annotation if field is not None else 'no kind field'}"
        )


def register_sensor(
    sensor_class: type,
    config_class: type[SensorConfigBase],
    *,
    build: Callable[[Any], Any] | None = None,
) -> SensorKind:
    """Make the sensor kind ``sensor_class.kind`` available to scenario files (module docstring).

    Raises ValueError for a kind that is not a lower-case identifier, a sensor class missing a
    member of the contract, a config class that does not derive from ``SensorConfigBase`` or
    whose ``kind`` is not ``Literal[kind]``, or a kind registered before with other classes
    (registering the same classes again is a no-op).
    """
    kind = getattr(sensor_class, "kind", None)
    if not (isinstance(kind, str) and _KIND_NAME.fullmatch(kind)):
        raise ValueError(
            f"sensor_class.kind must be a lower-case identifier ([a-z][a-z0-9_]*), got {kind!r}"
        )
    missing = [m for m in _CLASS_MEMBERS if not hasattr(sensor_class, m)]
    if missing:
        raise ValueError(
            f"sensor_class {sensor_class.__name__} lacks {missing} of the SensorModel contract "
            "(derive from activetrack.models.GaussianSensor for generic versions)"
        )
    _check_config(kind, config_class)
    old = _KINDS.get(kind)
    if old is not None:
        if (old.sensor_class, old.config_class) == (sensor_class, config_class):
            return old
        raise ValueError(
            f"sensor kind {kind!r} is registered already (with {old.sensor_class.__name__}); "
            "unregister_sensor it first"
        )
    entry = SensorKind(kind, sensor_class, config_class, build or _default_build(sensor_class))
    _KINDS[kind] = entry
    _changed()
    return entry


def unregister_sensor(kind: str) -> None:
    """Remove a registered kind (e.g. a test's); scenario files naming it no longer load."""
    if _KINDS.pop(kind, None) is None:
        raise ValueError(f"sensor kind must be one of {registered_kinds()}, got {kind!r}")
    _changed()


def registered_kinds() -> tuple[str, ...]:
    """The registered sensor kinds, in registration order."""
    return tuple(_KINDS)


def sensor_kind(kind: str) -> SensorKind:
    """The registration of ``kind``; ValueError listing the registered kinds otherwise."""
    try:
        return _KINDS[kind]
    except (KeyError, TypeError):
        raise ValueError(
            f"sensors.kind: must be one of {registered_kinds()}, got {kind!r}"
        ) from None


def sensor_config_union() -> Any:
    """The type of a ``sensors:`` entry: the registered configs, discriminated on ``kind``
    (None while no kind is registered)."""
    configs = tuple(entry.config_class for entry in _KINDS.values())
    if not configs:
        return None
    if len(configs) == 1:
        return configs[0]
    return Annotated[Union[configs], Field(discriminator="kind")]  # noqa: UP007


def on_registry_change(callback: Callable[[], None]) -> None:
    """Call ``callback()`` after every registration or removal (the schema rebuilds the models
    that hold sensor entries)."""
    _LISTENERS.append(callback)


def _changed() -> None:
    for callback in _LISTENERS:
        callback()
