"""The one planner: :class:`Planner` runs its :class:`PlannerStrategy` objects in order, each
``decide(context) -> DecisionPart`` seeing the epoch's tracks and platforms and what the
strategies before it decided (``context.so_far``).
"""

from __future__ import annotations

import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any, Protocol

import numpy as np

from activetrack.data import (
    BeamCommand,
    Command,
    Decision,
    PlanReportData,
    PlatformSnapshot,
    TrackEstimate,
    TrackSet,
)
from activetrack.planning.selection import TargetPrediction

__all__ = ["DecisionContext", "DecisionPart", "Planner", "PlannerStrategy", "SensorChoice"]


@dataclass(frozen=True)
class SensorChoice:
    """A sensor selection for epoch k+1: the chosen sensors (indices into the scenario's
    sensors, ascending, and their ids), every candidate's id and cost, and the label
    ``"<strategy>/<cost name>"``."""

    indices: tuple[int, ...]
    sensor_ids: tuple[str, ...]
    candidate_ids: tuple[str, ...]
    costs: tuple[float, ...]
    label: str


@dataclass(frozen=True)
class DecisionPart:
    """What one strategy (or all of them so far, merged by :meth:`then`) decided."""

    commands: tuple[Command, ...] = ()
    planned_pv: Mapping[str, np.ndarray] = field(default_factory=dict)  # platform pv at k+1
    prediction: TargetPrediction | None = None
    selection: SensorChoice | None = None
    report: PlanReportData | None = None
    evaluations: int = 0
    extra: Mapping[str, Any] = field(default_factory=dict)
    beams: tuple[BeamCommand, ...] = ()

    def then(self, later: DecisionPart) -> DecisionPart:
        """This part followed by ``later``: commands and beams appended, evaluations summed,
        mappings merged; a later prediction, selection or report replaces an earlier one."""
        return DecisionPart(
            commands=self.commands + later.commands,
            beams=self.beams + later.beams,
            planned_pv={**self.planned_pv, **later.planned_pv},
            prediction=later.prediction if later.prediction is not None else self.prediction,
            selection=later.selection if later.selection is not None else self.selection,
            report=later.report if later.report is not None else self.report,
            evaluations=self.evaluations + later.evaluations,
            extra={**self.extra, **later.extra},
        )

    def decision(self, epoch: int, wall_time_s: float) -> Decision:
        """The :class:`Decision`; the report counts the evaluations of every part."""
        report = self.report
        if report is not None:
            report = replace(report, evaluations=self.evaluations, wall_time_s=wall_time_s)
        sel = self.selection
        chosen: dict[str, Any] = {}
        if sel is not None:
            chosen = dict(
                selected_sensor_ids=sel.sensor_ids,
                candidate_sensor_ids=sel.candidate_ids,
                selection_costs=sel.costs,
                selection_criterion=sel.label,
            )
        return Decision(
            epoch, self.commands, self.beams, report=report, extra=dict(self.extra), **chosen
        )


@dataclass(frozen=True)
class DecisionContext:
    """The inputs of one decision at ``epoch``: the tracker's output, every platform's
    snapshot by id, the interval dt, and what the strategies before this one decided
    (``so_far``)."""

    epoch: int
    tracks: TrackSet
    platforms: Mapping[str, PlatformSnapshot]
    dt: float
    so_far: DecisionPart = DecisionPart()

    @property
    def track(self) -> TrackEstimate:
        """The track of the scene's one target (the papers' strategies plan for it)."""
        if len(self.tracks.tracks) != 1:
            raise ValueError(
                f"tracks: a single-target strategy needs one track, got {len(self.tracks.tracks)}"
            )
        return self.tracks.tracks[0]

    def next_pv(self, platform_id: str) -> np.ndarray:
        """The platform's pv at k+1: as planned so far, else coasting at its velocity."""
        planned = self.so_far.planned_pv.get(platform_id)
        if planned is not None:
            return np.asarray(planned, dtype=float)
        pv = np.asarray(self.platforms[platform_id].pv, dtype=float)
        return pv + self.dt * np.array([pv[1], 0.0, pv[3], 0.0])

    @property
    def prediction(self) -> TargetPrediction:
        """The MRE prediction for k+1 (an MRE prediction strategy must run first)."""
        if self.so_far.prediction is None:
            raise RuntimeError("planner: an MRE strategy ran without MrePrediction before it")
        return self.so_far.prediction


class PlannerStrategy(Protocol):
    """A part of the planner: reads the context, returns its part of the decision."""

    def decide(self, context: DecisionContext) -> DecisionPart: ...


class Planner:
    """Decides, each epoch, the manoeuvres, the beam pointings and the sensors that measure
    next by running ``strategies`` in order; ``platform_ids``: every platform whose state a
    decision needs; ``dt`` the decision interval."""

    def __init__(
        self, strategies: Sequence[PlannerStrategy], platform_ids: Sequence[str], dt: float
    ):
        self.strategies = tuple(strategies)
        self.platform_ids = tuple(platform_ids)
        self.dt = float(dt)

    def decide(
        self, epoch: int, tracks: TrackSet, snapshots: Sequence[PlatformSnapshot]
    ) -> Decision:
        """Commands for the leg epoch -> epoch+1 (hold course when the planner is off), beam
        pointings and the sensors that measure at epoch+1 (None: all of them)."""
        start = time.perf_counter()
        platforms = {s.platform_id: s for s in snapshots}
        missing = [pid for pid in self.platform_ids if pid not in platforms]
        if missing:
            raise ValueError(f"platform states missing for {missing}")
        part = DecisionPart()
        for strategy in self.strategies:
            context = DecisionContext(epoch, tracks, platforms, self.dt, part)
            part = part.then(strategy.decide(context))
        return part.decision(epoch, time.perf_counter() - start)
