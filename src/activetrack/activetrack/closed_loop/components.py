"""The closed loop's components built from a validated scenario: the simulator, the tracker
and the planner, each drawing from its own generator (:func:`component_rngs`)."""

from __future__ import annotations

import numpy as np

from activetrack.filters.registry import filter_kind, make_filter
from activetrack.kernels import expect_particle_work
from activetrack.models.clutter import ClutteredSensor
from activetrack.scenarios.build import build_motion_model, build_sensor
from activetrack.scenarios.schema import Scenario, TargetConfig
from activetrack.simulation.simulator import SimPlatform, SimTarget, Simulator
from activetrack.tracking.tracker import FilterSpec, Tracker, TrackPrior

__all__ = [
    "build_simulator",
    "build_tracker",
    "component_rngs",
    "known_association",
    "scene_sensors",
    "scene_targets",
]


def component_rngs(seed: int, run: int | None = None) -> tuple[np.random.Generator, ...]:
    """(sim, tracker, planner, evaluator) generators: one stream each, fixed by seed and run."""
    ss = np.random.SeedSequence(seed if run is None else [seed, run])
    return tuple(np.random.default_rng(s) for s in ss.spawn(4))


def scene_targets(scenario: Scenario) -> list[TargetConfig]:
    """The scenario's targets in order (one or many)."""
    return list(scenario.targets or [scenario.target])


def scene_sensors(scenario: Scenario) -> dict[str, tuple[str, ClutteredSensor]]:
    """Every sensor by id in scenario order: (platform id, the sensor in the scene: its field
    of view, clutter, and the tracker's gate unless the association is known)."""
    gate = scenario.tracker.tracks.gate_sigmas
    gated = not known_association(scenario)
    return {
        s.id: (p.id, ClutteredSensor.wrap(build_sensor(s), s, gate, gated))
        for p in scenario.platforms
        for s in p.sensors
    }


def known_association(scenario: Scenario) -> bool:
    """Whether every detection is known to be the one target's: one target, present from
    epoch 0 to the end, and no sensor with clutter (tracking: :mod:`activetrack.tracking`)."""
    targets = scene_targets(scenario)
    clutter = any(s.clutter_density > 0 for p in scenario.platforms for s in p.sensors)
    return len(targets) == 1 and targets[0].birth == 0 and targets[0].death is None and not clutter


def build_simulator(scenario: Scenario, rng: np.random.Generator) -> Simulator:
    """The scenario's targets and platforms, drawing from ``rng``."""
    sensors = scene_sensors(scenario)
    targets = [
        SimTarget(
            t.id,
            build_motion_model(t.motion),
            np.array(t.prior.mean, dtype=float),
            t.prior.covariance(),
            None if t.initial_state is None else np.array(t.initial_state, dtype=float),
            t.birth,
            t.death,
        )
        for t in scene_targets(scenario)
    ]
    platforms = [
        SimPlatform(
            p.id,
            np.array(p.initial_state, dtype=float),
            p.limits if p.controllable else None,
            tuple((s.id, sensors[s.id][1]) for s in p.sensors),
        )
        for p in scenario.platforms
    ]
    return Simulator(targets, platforms, scenario.dt, scenario.steps, rng)


def build_tracker(scenario: Scenario, rng: np.random.Generator) -> Tracker:
    """The scenario's tracker: its filter on every track, the targets present at epoch 0 as
    confirmed tracks from their priors, drawing from ``rng``."""
    cfg = scenario.tracker
    motion_cfg = cfg.motion or scenario.target.motion
    model = build_motion_model(motion_cfg)
    kind = filter_kind(cfg.filter)
    if kind.particle_based:  # a long run loads the PF kernels now, not in mid-run
        expect_particle_work(scenario.steps * cfg.particles)

    def make(x0: np.ndarray, P0: np.ndarray, t0: float):
        return make_filter(cfg.filter, model, x0, P0, cfg, rng, t0)

    priors = [
        TrackPrior(
            t.id,
            np.array(t.prior.mean, dtype=float),
            np.array(t.prior.covariance(), dtype=float),
            t.priority,
        )
        for t in scene_targets(scenario)
        if t.birth == 0
    ]
    return Tracker(
        model,
        motion_cfg.model,
        FilterSpec(cfg.filter, kind.particle_based, make),
        {sid: sensor for sid, (_, sensor) in scene_sensors(scenario).items()},
        priors,
        known_association=known_association(scenario),
        management=cfg.tracks,
        planner_samples=cfg.planner_samples,
        new_track_priority=scenario.planner.targets.new_track_priority,
        rng=rng,
    )
