"""Scenario sections and rules of multi-target scenarios (a ``targets:`` list).

A scenario with ``targets:`` runs the multi-target loop (:mod:`activetrack.multitarget`): the
simulator draws detections of every target with each sensor's ``pd``, Poisson clutter of
``clutter_density`` over each sensor's field of view and no labels; the tracker associates them
(JPDA) and manages tracks (M-of-N); the planner serves every track. The sections here:

- ``tracker.tracks`` (:class:`TrackManagementConfig`): gate, confirmation and deletion,
  initiation;
- ``planner.targets`` (:class:`MultiTargetPlanConfig`): how costs over tracks combine and how
  steerable beams are assigned to tracks;
- ``evaluation`` (:class:`EvaluationConfig`): OSPA / GOSPA cut-off and order.

Units: metres, seconds, radians.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from activetrack.limits import MAX_CLUTTER_PER_SCAN, MAX_GATE_SIGMAS, MAX_RANGE, MAX_TRACKS

if TYPE_CHECKING:
    from activetrack.scenarios.schema import Scenario

__all__ = [
    "EvaluationConfig",
    "MultiTargetPlanConfig",
    "TrackManagementConfig",
    "fov_volume",
    "multitarget_problems",
]

# Sensor kinds that can report clutter and how many measurement components they have.
CLUTTER_KINDS = ("bearing", "range_bearing")


class _Strict(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class TrackManagementConfig(_Strict):
    """JPDA gating and M-of-N track management of the multi-target tracker.

    A track is confirmed once it had a gated detection in ``confirm_m`` of its last
    ``confirm_n`` looks (epochs where a sensor looked at its predicted position); a tentative
    track that cannot reach that any more is deleted, and a confirmed one after
    ``delete_misses`` consecutive looks without a gated detection, or when its position
    standard deviation exceeds ``max_position_std``. New tracks start from detections of
    range-bearing sensors that no track gated, with velocity zero and ``init_speed_std``.
    """

    gate_sigmas: Annotated[float, Field(gt=0, le=MAX_GATE_SIGMAS)] = 3.5
    confirm_m: Annotated[int, Field(ge=1, le=100)] = 2
    confirm_n: Annotated[int, Field(ge=1, le=100)] = 3
    delete_misses: Annotated[int, Field(ge=1, le=1000)] = 4
    init_speed_std: Annotated[float, Field(gt=0, le=1e6)] = 10.0  # m/s
    max_position_std: Annotated[float, Field(gt=0, le=MAX_RANGE)] = 1e5  # m
    max_tracks: Annotated[int, Field(ge=1, le=MAX_TRACKS)] = 50

    @model_validator(mode="after")
    def _m_of_n(self) -> TrackManagementConfig:
        if self.confirm_m > self.confirm_n:
            raise ValueError(
                f"confirm_m: must be <= confirm_n ({self.confirm_n}), got {self.confirm_m}"
            )
        return self


class MultiTargetPlanConfig(_Strict):
    """Planning across tracks.

    ``aggregate``: ``worst`` minimises the largest per-track cost (the worst target's b_k),
    ``weighted_sum`` the sum of per-track costs weighted by the target's ``priority`` (tracks
    started from detections weigh ``new_track_priority``). Only confirmed tracks count.
    ``assignment``: how sensors with a steerable beam (``beam_width``) are pointed, one track
    each per epoch: ``mre`` the optimal assignment of the per-pair MRE cost, ``random``
    uniformly (the baseline), ``nearest`` the closest track.
    """

    aggregate: Literal["worst", "weighted_sum"] = "worst"
    assignment: Literal["mre", "random", "nearest"] = "mre"
    new_track_priority: Annotated[float, Field(gt=0, le=1e6)] = 1.0


class EvaluationConfig(_Strict):
    """OSPA (Schuhmacher et al. 2008) and GOSPA (Rahmathullah et al. 2017) parameters:
    cut-off ``c`` [m], order ``p`` and GOSPA's ``alpha`` (2: the metric splits into
    localisation, missed and false-target terms)."""

    cutoff: Annotated[float, Field(gt=0, le=MAX_RANGE)] = 1000.0
    order: Annotated[float, Field(ge=1, le=100)] = 2.0
    alpha: Annotated[float, Field(gt=0, le=2)] = 2.0


def fov_volume(kind: str, width: float, r_min: float, r_max: float) -> float:
    """Volume of a sensor's field of view in measurement units: the bearing sector ``width``
    [rad] for a bearing sensor, times the range interval [m] for a range-bearing one."""
    if kind == "range_bearing":
        return width * (r_max - r_min)
    return width


def _sensor_problems(s: Scenario, multi: bool) -> list[tuple[str, str]]:
    out: list[tuple[str, str]] = []
    for i, p in enumerate(s.platforms):
        for j, sensor in enumerate(p.sensors):
            where = f"platforms.{i}.sensors.{j}"
            fov = (sensor.clutter_density, sensor.fov_width, sensor.beam_width)
            if not multi and (fov[0] > 0 or fov[1] is not None or fov[2] is not None):
                out.append(
                    (
                        f"{where}.clutter_density",
                        "clutter_density, fov_width and beam_width need a multi-target "
                        "scenario (a targets: list)",
                    )
                )
                continue
            if sensor.fov_width is not None and sensor.beam_width is not None:
                out.append((f"{where}.beam_width", "give fov_width or beam_width, not both"))
            if sensor.clutter_density > 0:
                if sensor.kind not in CLUTTER_KINDS:
                    out.append(
                        (
                            f"{where}.clutter_density",
                            f"clutter is modelled for sensor kinds {CLUTTER_KINDS}, "
                            f"got kind {sensor.kind!r}",
                        )
                    )
                    continue
                if sensor.kind == "range_bearing" and not math.isfinite(sensor.r_max):
                    out.append(
                        (
                            f"{where}.r_max",
                            "must be finite for a range-bearing sensor with clutter (the "
                            "clutter is uniform over [r_min, r_max])",
                        )
                    )
                    continue
                width = sensor.beam_width or sensor.fov_width or 2.0 * math.pi
                mean = sensor.clutter_density * fov_volume(
                    sensor.kind, width, sensor.r_min, sensor.r_max
                )
                if mean > MAX_CLUTTER_PER_SCAN:
                    out.append(
                        (
                            f"{where}.clutter_density",
                            f"the mean false alarms per scan (density x field of view "
                            f"{mean:.3g}) must be <= {MAX_CLUTTER_PER_SCAN:g}",
                        )
                    )
    return out


def multitarget_problems(s: Scenario) -> list[tuple[str, str]]:
    """``(field, message)`` for every violated rule of multi-target scenarios."""
    multi = s.targets is not None
    out = _sensor_problems(s, multi)
    if not multi:
        return out
    assert s.targets is not None
    ids = [t.id for t in s.targets]
    dupes = sorted({v for v in ids if ids.count(v) > 1})
    if dupes:
        out.append(("targets", f"target ids must be unique, repeated: {dupes}"))
    for i, t in enumerate(s.targets):
        if t.birth >= s.steps:
            out.append((f"targets.{i}.birth", f"must be < steps ({s.steps}), got {t.birth}"))
        if t.death is not None and t.death <= t.birth:
            out.append((f"targets.{i}.death", f"must be > birth ({t.birth}), got {t.death}"))
        if t.motion.model not in ("ncv", "ncv_discrete"):
            out.append(
                (
                    f"targets.{i}.motion.model",
                    f"multi-target scenarios need NCV pv targets ('ncv', 'ncv_discrete'), "
                    f"got {t.motion.model!r}",
                )
            )
    kinds = {sensor.kind for p in s.platforms for sensor in p.sensors}
    if any(t.birth > 0 for t in s.targets) and "range_bearing" not in kinds:
        out.append(
            (
                "targets",
                "a target born after epoch 0 needs a range_bearing sensor to start its track "
                "from detections (bearings-only tracks start from the priors of the targets "
                "present at epoch 0)",
            )
        )
    if s.tracker.filter not in ("ekf", "pf"):
        out.append(
            (
                "tracker.filter",
                f"must be 'ekf' (JPDA-EKF) or 'pf' (clutter-aware particle filters) in a "
                f"multi-target scenario, got {s.tracker.filter!r}",
            )
        )
    cfg = s.planner
    if cfg.enabled and (cfg.search == "cautious" or cfg.selection.enabled):
        out.append(
            (
                "planner",
                "multi-target planning steers platforms and points beams; search 'cautious' "
                "and planner.selection are single-target",
            )
        )
    if cfg.enabled and cfg.mode != "renewal":
        out.append(("planner.mode", "must be 'renewal' in a multi-target scenario"))
    return out
