"""The tracker-only configuration (YAML): what tracking recorded detections needs (its fields:
docs/track-your-data.md).

Only the tracker's side of a scenario: the sensors grouped by the platform that carries them
(where a platform was comes with each scan), the tracker section (``tracker.motion`` required:
no target motion to fall back on), optionally the targets known at epoch 0 (their tracks start
confirmed from their priors) and the evaluation. The scans of epoch k are at t = k dt.
:func:`tracking_of` takes a scenario's, so that the tracker built from it is the scenario's
own. As in the scenario's schema, these classes check the shape; the rules that ask registries
and components are :func:`activetrack.scenarios.rules.tracking_problems`, run by the loader.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from activetrack import limits
from activetrack.scenarios.fields import (
    MOTION_STATE,
    Dt,
    Seed,
    Steps,
    Strict,
    check_state,
    float_range,
    identifier,
)
from activetrack.scenarios.plugins import Plugins
from activetrack.scenarios.registry import on_registry_change
from activetrack.scenarios.schema import (
    EvaluationConfig,
    PriorConfig,
    Scenario,
    SensorConfig,
    TrackerConfig,
    check_platform_ids,
)

__all__ = [
    "ASSOCIATIONS",
    "TrackedTargetConfig",
    "TrackingConfig",
    "TrackingPlatformConfig",
    "tracking_of",
]

# known: every detection is the one target's (one target, no clutter); jpda: associated and
# managed tracks; auto: known for one target without clutter, else jpda (as a scenario decides).
ASSOCIATIONS = ("auto", "known", "jpda")


class TrackingPlatformConfig(Strict):
    """A platform: its id and sensors (no initial state: each scan says where it was)."""

    id: Annotated[str, identifier("a platform id")]
    sensors: list[SensorConfig] = Field(min_length=1, max_length=limits.MAX_SENSORS)


class TrackedTargetConfig(Strict):
    """A target known at epoch 0: its track starts confirmed from ``prior`` (in the state of
    ``tracker.motion``), weighed ``priority`` by a planner."""

    id: Annotated[str, identifier("the target id")]
    prior: PriorConfig
    priority: Annotated[float, float_range(gt=0, hi=1e6)] = 1.0


class TrackingConfig(Strict):
    name: Annotated[
        str, identifier("the name (it names the output folder)", limits.MAX_NAME_LENGTH)
    ]
    description: str = Field(default="", max_length=limits.MAX_DESCRIPTION_LENGTH)
    # Modules that register kinds, filters; imported first, as a scenario's (scenarios.plugins).
    plugins: Plugins = Field(default=[])
    seed: Seed = 0  # the tracker's generator (with --run: component_rngs)
    dt: Dt  # s between epochs: the scans of epoch k are at t = k dt
    # The last epoch the data may hold: a scenario's steps (a file with ``steps:`` is read as
    # a scenario); None: any.
    steps: Steps | None = None
    platforms: list[TrackingPlatformConfig] = Field(min_length=1, max_length=limits.MAX_PLATFORMS)
    tracker: TrackerConfig
    targets: list[TrackedTargetConfig] = Field(default=[], max_length=limits.MAX_TARGETS)
    association: Literal["auto", "known", "jpda"] = "auto"
    # The planner weight of a track started from detections (a scenario's
    # planner.targets.new_track_priority): tracks carry it.
    new_track_priority: Annotated[float, float_range(gt=0, hi=1e6)] = 1.0
    evaluation: EvaluationConfig = EvaluationConfig()

    @field_validator("platforms")
    @classmethod
    def _unique_ids(cls, platforms: list[TrackingPlatformConfig]) -> list[TrackingPlatformConfig]:
        return check_platform_ids(platforms)

    @model_validator(mode="after")
    def _targets_in_the_trackers_state(self) -> TrackingConfig:
        """``tracker.motion`` is given; every prior is in its state; target ids are unique."""
        motion = self.tracker.motion
        if motion is None:
            raise ValueError(
                "tracker.motion: required in a tracker configuration (the motion model the "
                "filters assume, e.g. {model: ncv, q: 1.0})"
            )
        names = MOTION_STATE[motion.model]
        problems = []
        for i, t in enumerate(self.targets):
            if len(t.prior.mean) != len(names):
                problems.append(
                    f"targets.{i}.prior.mean: must have {len(names)} entries {names} for "
                    f"tracker.motion {motion.model}, got {len(t.prior.mean)}"
                )
                continue
            try:
                check_state(t.prior.mean, names)
            except ValueError as exc:
                problems.append(f"targets.{i}.prior.mean: {exc}")
        ids = [t.id for t in self.targets]
        dupes = sorted({v for v in ids if ids.count(v) > 1})
        if dupes:
            problems.append(f"targets: target ids must be unique, repeated: {dupes}")
        if problems:
            raise ValueError("\n".join(problems))
        return self

    @property
    def known_association(self) -> bool:
        """Whether every detection is the one target's (``association``; ``auto``: one target
        and no sensor with clutter). Otherwise the tracker associates (JPDA) and manages
        tracks."""
        if self.association != "auto":
            return self.association == "known"
        clutter = any(s.clutter_density > 0 for p in self.platforms for s in p.sensors)
        return len(self.targets) == 1 and not clutter

    @property
    def sensor_ids(self) -> tuple[str, ...]:
        """Every sensor id, in configuration order (the order scans of an epoch are applied)."""
        return tuple(s.id for p in self.platforms for s in p.sensors)


def _rebuild_sensor_models() -> None:
    """Rebuild the models holding sensor entries after a kind was (un)registered."""
    TrackingPlatformConfig.model_rebuild(force=True)
    TrackingConfig.model_rebuild(force=True)


on_registry_change(_rebuild_sensor_models)


def tracking_of(scenario: Scenario) -> TrackingConfig:
    """The tracker configuration of a valid scenario, its tracker exactly: the targets present
    at epoch 0 as priors, the first target's motion unless ``tracker.motion`` is given."""
    motion = scenario.tracker.motion or scenario.target.motion
    return TrackingConfig(
        name=scenario.name,
        description=scenario.description,
        plugins=scenario.plugins,
        seed=scenario.seed,
        dt=scenario.dt,
        steps=scenario.steps,
        platforms=[TrackingPlatformConfig(id=p.id, sensors=p.sensors) for p in scenario.platforms],
        tracker=scenario.tracker.model_copy(update={"motion": motion}),
        targets=[
            TrackedTargetConfig(id=t.id, prior=t.prior, priority=t.priority)
            for t in scenario.targets
            if t.birth == 0
        ],
        association="known" if scenario.known_association else "jpda",
        new_track_priority=scenario.planner.targets.new_track_priority,
        evaluation=scenario.evaluation,
    )
