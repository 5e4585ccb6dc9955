"""The planner of the closed loop: one decision per epoch from the tracker's posterior.

:class:`PlannerCore` is the facade the batch loop and the ROS planner node call,
``PlannerCore(scenario, rng).decide(epoch, track, snapshots) -> Decision``. It runs the
strategies :func:`build_strategies` composes from the scenario's ``planner`` section
(:mod:`activetrack.closed_loop.strategies`):

- ``enabled: false``: HoldCourse;
- ``search: cautious``: CautiousLocalisation (Vander Hook et al.);
- ``cost: pcrlb`` without selection: PcrlbPlanning (Hernandez);
- ``cost: mre`` and/or ``selection.enabled`` (Ramdaras): MrePrediction, then for the
  controllable platforms PcrlbPlanning (``cost: pcrlb``) or MrePositioning (``cost: mre``), then
  the selection strategy of ``selection.strategy`` (``SELECTION_STRATEGIES``: MreSelection,
  TraceSelection, RandomSelection, FixedSelection), then MreOutlook (the plan report).

MRE covariance (docs/ramdaras.md): in renewal mode each decision starts from the track,
P_{k+1|k} = F P_{k|k} F^T + Q and x_{k+1|k} = F x_{k|k} (Ramdaras Fig. 5: the filter's
P_{k|k} feeds the positioning and selection). In open-loop mode the planner keeps its own
recursion from the prior: P_{k+1|k+1} = (1 - pd) P_{k+1|k} + pd P^(j)_{k+1|k+1} for the selected
sensors at their planned positions, linearised at the noise-free predicted mean (the MRE bound
the tests compare the filter against).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence

import numpy as np

from activetrack.closed_loop.strategies import (
    MRE_REPORT_COSTS,
    CautiousLocalisation,
    DecisionContext,
    DecisionPart,
    FixedSelection,
    HoldCourse,
    LinearDynamics,
    MreOutlook,
    MrePositioning,
    MrePrediction,
    MreSelection,
    PcrlbPlanning,
    PlannerStrategy,
    RandomSelection,
    SensorEntry,
    TraceSelection,
    sensor_entries,
)
from activetrack.data import Decision, PlatformSnapshot, TrackSet
from activetrack.scenarios.schema import Scenario, SelectionConfig

__all__ = [
    "MRE_REPORT_COSTS",
    "SELECTION_STRATEGIES",
    "PlannerCore",
    "build_planner",
    "build_strategies",
]

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


def build_strategies(scenario: Scenario, rng: np.random.Generator) -> tuple[PlannerStrategy, ...]:
    """The strategies a scenario's planner runs, in order (table in the module docstring)."""
    cfg = scenario.planner
    controllable = tuple(p.id for p in scenario.platforms if p.controllable)
    if not cfg.enabled:
        return (HoldCourse(controllable),)
    if controllable and cfg.search == "cautious":
        # Stop-and-measure localisation replaces manoeuvre planning.
        return (CautiousLocalisation(scenario),)
    mre = (cfg.cost == "mre" and bool(controllable)) or cfg.selection.enabled
    if not controllable and not mre:
        return (HoldCourse(()),)
    dynamics = LinearDynamics.of(scenario)
    if not mre:
        return (PcrlbPlanning(scenario, dynamics, rng),)
    sensors = sensor_entries(scenario)
    predictor = MrePrediction(scenario, dynamics)
    stages: list[PlannerStrategy] = [predictor]
    if controllable and cfg.cost == "pcrlb":
        stages.append(PcrlbPlanning(scenario, dynamics, rng))
    elif controllable:
        stages.append(MrePositioning(scenario, sensors, dynamics.dt))
    criterion = cfg.criterion
    if cfg.selection.enabled:
        stages.append(SELECTION_STRATEGIES[cfg.selection.strategy](sensors, cfg.selection, rng))
        criterion = cfg.selection.criterion
    search = cfg.search if controllable and cfg.cost == "mre" else "none"
    stages.append(MreOutlook(scenario, sensors, predictor, criterion, search))
    return tuple(stages)


class PlannerCore:
    """Decides the manoeuvres of the controllable platforms and the sensors that measure next;
    draws only from its own ``rng``."""

    def __init__(self, scenario: Scenario, rng: np.random.Generator):
        self.scenario = scenario
        self.platform_ids = tuple(p.id for p in scenario.platforms)
        self.strategies = build_strategies(scenario, rng)

    def decide(
        self, epoch: int, tracks: TrackSet, snapshots: Sequence[PlatformSnapshot]
    ) -> Decision:
        """Commands for the leg epoch -> epoch+1 (hold course when the planner is off) and the
        sensors that measure at epoch+1 (None: all of them), from the scene's one track."""
        start = time.perf_counter()
        if len(tracks.tracks) != 1:
            raise ValueError(f"tracks: the single-target planner needs one track, got {tracks}")
        track = tracks.tracks[0]
        platforms = {s.platform_id: s for s in snapshots}
        missing = [pid for pid in self.platform_ids if pid not in platforms]
        if missing:
            raise ValueError(f"platform states missing for {missing}")
        part = DecisionPart()
        for strategy in self.strategies:
            context = DecisionContext(epoch, track, platforms, self.scenario.dt, part)
            part = part.then(strategy.decide(context))
        return part.decision(epoch, time.perf_counter() - start)


def build_planner(scenario: Scenario, rng: np.random.Generator):
    """The scenario's planner, drawing from ``rng``: the papers' strategies for a scene of one
    target whose detections are known to be its own (no clutter) and no steerable beam,
    planning across tracks with beam assignment otherwise."""
    from activetrack.closed_loop.components import known_association

    beams = any(s.beam_width is not None for p in scenario.platforms for s in p.sensors)
    if beams or not known_association(scenario):
        from activetrack.multitarget.planner import MultiTargetPlanner

        return MultiTargetPlanner(scenario, rng)
    return PlannerCore(scenario, rng)
