"""The planner of the closed loop: one decision per epoch from the tracker's posterior.

PCRLB manoeuvre planning (Hernandez) through :func:`activetrack.planning.planner.plan`, in
renewal mode (each decision starts from the posterior, footnote 2) or open loop (from the
prior and the known dynamics, sec. 3.2).
"""

from __future__ import annotations

import time

import numpy as np

from activetrack.bounds.pcrlb import covariance_bound
from activetrack.closed_loop.data import (
    Command,
    Decision,
    PlanReportData,
    PlatformSnapshot,
    TrackSnapshot,
)
from activetrack.planning.planner import (
    PlannerPlatform,
    PlanSettings,
    TargetBelief,
    advance_belief,
    plan,
    platforms_from_scenario,
)
from activetrack.scenarios.build import build_motion_model
from activetrack.scenarios.schema import Scenario


class PlannerCore:
    """Decides the manoeuvres of the controllable platforms; draws only from its own ``rng``."""

    def __init__(self, scenario: Scenario, rng: np.random.Generator):
        self.scenario = scenario
        self.cfg = scenario.planner
        self.rng = rng
        self.dt = scenario.dt
        model = build_motion_model(scenario.target.motion)
        self.controllable = tuple(p.id for p in scenario.platforms if p.controllable)
        self.active = self.cfg.enabled and bool(self.controllable)
        self.settings = None
        self._open_loop_belief = None
        if self.active:
            if not getattr(model, "is_linear", False):
                raise ValueError(
                    f"planner: PCRLB planning needs linear target dynamics (ncv, ncv_discrete, "
                    f"constant_turn), got motion {scenario.target.motion.model!r}"
                )
            self.F = model.transition_matrix(self.dt)
            self.Q = model.process_noise(self.dt)
            self.settings = PlanSettings.from_config(self.cfg)

    def _platforms(self, snapshots: list[PlatformSnapshot]) -> list[PlannerPlatform]:
        states = {s.platform_id: s.pv for s in snapshots}
        missing = [p.id for p in self.scenario.platforms if p.id not in states]
        if missing:
            raise ValueError(f"platform states missing for {missing}")
        return platforms_from_scenario(self.scenario, states)

    def _belief(self, epoch: int, track: TrackSnapshot, platforms) -> TargetBelief:
        if self.cfg.mode == "open_loop":
            if self._open_loop_belief is None:
                prior = self.scenario.target.prior
                self._open_loop_belief = TargetBelief.from_gaussian(
                    np.array(prior.mean), prior.covariance(), self.cfg.mc_samples, self.rng
                )
            elif epoch > 0:
                self._open_loop_belief = advance_belief(
                    self._open_loop_belief, platforms, self.F, self.Q, self.rng
                )
            return self._open_loop_belief
        if track.mean.shape != (4,):
            raise ValueError(
                f"track: renewal planning needs a pv track (x, xdot, y, ydot), got "
                f"{track.state_names}"
            )
        if track.samples is not None:
            return TargetBelief(covariance_bound(track.cov), track.samples)
        return TargetBelief.from_gaussian(track.mean, track.cov, self.cfg.mc_samples, self.rng)

    def decide(
        self, epoch: int, track: TrackSnapshot, snapshots: list[PlatformSnapshot]
    ) -> Decision:
        """Commands for the leg epoch -> epoch+1 (hold course when the planner is off)."""
        start = time.perf_counter()
        if not self.active:
            commands = tuple(Command(pid, epoch, 0.0, 0.0) for pid in self.controllable)
            return Decision(epoch, commands)
        platforms = self._platforms(snapshots)
        belief = self._belief(epoch, track, platforms)
        result = plan(
            platforms, belief, self.settings, F=self.F, Q=self.Q, dt=self.dt, rng=self.rng
        )
        commands = tuple(
            Command(m.platform_id, epoch, m.heading_change, m.speed_change, m.heading, m.speed)
            for m in result.manoeuvres
        )
        r = result.report
        report = PlanReportData(
            epoch=epoch,
            cost_kind=self.cfg.cost,
            criterion=r.criterion,
            search=r.search,
            horizon=r.horizon,
            cost_names=r.cost_names,
            predicted_costs=tuple(float(c) for c in r.predicted_costs),
            evaluations=r.evaluations,
            wall_time_s=time.perf_counter() - start,
        )
        return Decision(epoch, commands, report=report)
