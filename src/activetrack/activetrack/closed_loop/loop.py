"""The closed loop without ROS: simulator, tracker and planner in one loop (docs/closed-loop.md).

:func:`run_once` is the reference the ROS graph reproduces exactly in lockstep mode, for every
scenario (one target or many). Each epoch k: the planner decides from the tracks of epoch k
(manoeuvres for the leg to k+1, beam pointings and the sensor selection for k+1), the
simulator applies the decision (commands, then beams, then the selection) and advances to
k+1, the tracker takes the epoch's scans.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import Protocol

import numpy as np

from activetrack.closed_loop.components import (
    build_planner,
    build_simulator,
    build_tracker,
    component_rngs,
)
from activetrack.closed_loop.record import RunRecord
from activetrack.data import Decision, PlatformSnapshot, TrackSet
from activetrack.scenarios.schema import Scenario
from activetrack.simulation.simulator import Simulator

__all__ = ["PlannerLike", "apply_decision", "run_once"]


class PlannerLike(Protocol):
    """What the loop asks of a planner (:class:`activetrack.planning.decision.Planner`, or
    another one to compare against: the benchmarks' Stone Soup sensor manager)."""

    def decide(
        self, epoch: int, tracks: TrackSet, platforms: Sequence[PlatformSnapshot]
    ) -> Decision: ...


PlannerFactory = Callable[[Scenario, np.random.Generator], PlannerLike]


def apply_decision(sim: Simulator, decision: Decision) -> int:
    """The decision's commands, beams and selection applied to ``sim``; the clamps."""
    clamps = 0
    for cmd in decision.commands:
        clamps += sim.apply_command(cmd).clamped
    for beam in decision.beams:
        sim.apply_beam(beam)
    if decision.selected_sensor_ids is not None:
        sim.apply_selection(decision.selected_sensor_ids)
    return clamps


def run_once(
    scenario: Scenario, run: int | None = None, planner_factory: PlannerFactory | None = None
) -> RunRecord:
    """One closed-loop run with the generators of (seed, run); the planner is
    ``planner_factory(scenario, planner_rng)`` (default: the scenario's)."""
    sim_rng, trk_rng, plan_rng, _ = component_rngs(scenario.seed, run)
    start = time.perf_counter()
    sim = build_simulator(scenario, sim_rng)
    tracker = build_tracker(scenario, trk_rng)
    planner = (planner_factory or build_planner)(scenario, plan_rng)
    platform_ids = tuple(sim.platforms)
    tracks = tracker.snapshot()
    track_sets: list[TrackSet] = []
    truth, paths = [], []  # epochs 0..K, as track_sets
    record = RunRecord(
        target_ids=sim.target_ids,
        sensor_ids=tuple(sim.sensors),
        platform_ids=platform_ids,
        truth=np.empty(0),
        tracks=track_sets,
        platform_paths=np.empty(0),
    )
    looked, detected, observed = [], [], []
    for k in range(scenario.steps + 1):
        if k > 0:
            scans = sim.advance()
            tracks = tracker.step(k, sim.time, scans)
            record.scans.append(scans)
            record.scan_truth.append(sim.last_truth)
            looked.append(sim.looked.copy())
            seen = {scan.sensor_id for scan in scans if len(scan.Z)}
            detected.append([sid in seen for sid in record.sensor_ids])
            observed.append(sim.last_observed.copy())
        truth.append(sim.truth_array())
        track_sets.append(tracks.without_samples())
        paths.append(np.stack([sim.platforms[i].pv for i in platform_ids]))
        if k < scenario.steps:
            decision = planner.decide(k, tracks, sim.platform_snapshots())
            record.decisions.append(decision)
            if decision.report is not None:
                record.evaluations += decision.report.evaluations
                record.planning_time_s += decision.report.wall_time_s
            record.clamps += apply_decision(sim, decision)
    K, S, N = scenario.steps, len(record.sensor_ids), len(record.target_ids)
    record.truth = np.array(truth)
    record.platform_paths = np.array(paths)
    record.looked = np.array(looked, dtype=bool).reshape(K, S)
    record.detected = np.array(detected, dtype=bool).reshape(K, S)
    record.observed = np.array(observed, dtype=bool).reshape(K, S, N)
    record.wall_time_s = time.perf_counter() - start
    return record
