"""The planner of the closed loop: one decision per epoch from the tracker's posterior.

- PCRLB manoeuvre planning (Hernandez) through :func:`activetrack.planning.planner.plan`
  (``planner.cost: pcrlb``), in renewal mode (each decision starts from the posterior,
  footnote 2) or open loop (from the prior and the known dynamics, sec. 3.2).
- MRE sensor positioning (Ramdaras sec. 4, ``planner.cost: mre``) of the controllable
  platforms, then sensor selection (sec. 3, eq. 27, ``planner.selection.enabled``) among all
  sensors at their planned positions: :mod:`activetrack.planning.selection`. Selection also
  follows a PCRLB plan when both are configured.

MRE covariance (docs/ramdaras.md): in renewal mode each decision starts from the track,
P_{k+1|k} = F P_{k|k} F^T + Q and x_{k+1|k} = F x_{k|k} (Ramdaras Fig. 5: the filter's
P_{k|k} feeds the positioning and selection). In open-loop mode the planner keeps its own
recursion from the prior: P_{k+1|k+1} = (1 - pd) P_{k+1|k} + pd P^(j)_{k+1|k+1} for the selected
sensors at their planned positions, linearised at the noise-free predicted mean (the MRE bound
the tests compare the filter against).
"""

from __future__ import annotations

import time

import numpy as np

from activetrack.bounds.costs import position_determinant, trace_cost
from activetrack.bounds.pcrlb import covariance_bound
from activetrack.closed_loop.cautious import CautiousController
from activetrack.closed_loop.data import (
    Command,
    Decision,
    PlanReportData,
    PlatformSnapshot,
    TrackSnapshot,
)
from activetrack.planning.manoeuvre import PlatformLimits
from activetrack.planning.planner import (
    PlannerPlatform,
    PlanSettings,
    TargetBelief,
    advance_belief,
    plan,
    platforms_from_scenario,
)
from activetrack.planning.selection import (
    MRE_CRITERIA,
    POSITIONING_SEARCHES,
    expected_update,
    mre_criterion,
    position_platform,
    select_sensors,
)
from activetrack.scenarios.build import build_motion_model, build_sensor
from activetrack.scenarios.schema import Scenario

# Cost names of the plan report in MRE mode (predicted for the epoch decided for, k+1).
MRE_REPORT_COSTS = ("objective", "det_pos", "trace", "det_pos_updated", "trace_updated")


class PlannerCore:
    """Decides the manoeuvres of the controllable platforms and the sensors that measure next;
    draws only from its own ``rng``."""

    def __init__(self, scenario: Scenario, rng: np.random.Generator):
        self.scenario = scenario
        self.cfg = scenario.planner
        self.rng = rng
        self.dt = scenario.dt
        model = build_motion_model(scenario.target.motion)
        self.controllable = tuple(p.id for p in scenario.platforms if p.controllable)
        self.active = self.cfg.enabled and bool(self.controllable)
        # Stop-and-measure localisation (Vander Hook et al.) replaces manoeuvre planning.
        self.cautious = (
            CautiousController(scenario) if self.active and self.cfg.search == "cautious" else None
        )
        self.pcrlb = self.active and self.cfg.cost == "pcrlb" and self.cautious is None
        self.mre_positioning = self.active and self.cfg.cost == "mre"
        self.selecting = self.cfg.enabled and self.cfg.selection.enabled
        self.settings = None
        self._open_loop_belief = None
        self._mre_state = None  # open loop: (x, P) the MRE recursion's posterior
        needs_linear = self.pcrlb or self.mre_positioning or self.selecting
        if needs_linear and not getattr(model, "is_linear", False):
            raise ValueError(
                f"planner: PCRLB / MRE planning needs linear target dynamics (ncv, ncv_discrete, "
                f"constant_turn), got motion {scenario.target.motion.model!r}"
            )
        if needs_linear:
            self.F = model.transition_matrix(self.dt)
            self.Q = model.process_noise(self.dt)
        if self.pcrlb:
            self.settings = PlanSettings.from_config(self.cfg)
        if self.mre_positioning:
            if self.cfg.criterion not in MRE_CRITERIA:
                raise ValueError(
                    f"planner.criterion must be one of {MRE_CRITERIA} with cost 'mre', "
                    f"got {self.cfg.criterion!r}"
                )
            if self.cfg.search not in POSITIONING_SEARCHES:
                raise ValueError(
                    f"planner.search must be one of {POSITIONING_SEARCHES} with cost 'mre', "
                    f"got {self.cfg.search!r}"
                )
        # Every sensor in scenario order: (sensor id, platform id, model).
        self.sensors = tuple(
            (s.id, p.id, build_sensor(s)) for p in scenario.platforms for s in p.sensors
        )
        sel = self.cfg.selection
        if self.selecting and sel.count > len(self.sensors):
            raise ValueError(
                f"planner.selection.count must be <= {len(self.sensors)} sensors, got {sel.count}"
            )
        self._fixed_index = None
        if self.selecting and sel.strategy == "fixed":
            self._fixed_index = [s[0] for s in self.sensors].index(sel.fixed_sensor)

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
        self._require_pv(track)
        if track.samples is not None:
            return TargetBelief(covariance_bound(track.cov), track.samples)
        return TargetBelief.from_gaussian(track.mean, track.cov, self.cfg.mc_samples, self.rng)

    @staticmethod
    def _require_pv(track: TrackSnapshot) -> None:
        if track.mean.shape != (4,):
            raise ValueError(
                f"track: renewal planning needs a pv track (x, xdot, y, ydot), got "
                f"{track.state_names}"
            )

    def decide(
        self, epoch: int, track: TrackSnapshot, snapshots: list[PlatformSnapshot]
    ) -> Decision:
        """Commands for the leg epoch -> epoch+1 (hold course when the planner is off) and the
        sensors that measure at epoch+1 (None: all of them)."""
        start = time.perf_counter()
        if self.cautious is not None:
            robot = next(s for s in snapshots if s.platform_id == self.cautious.robot_id)
            command = self.cautious.decide(epoch, track, robot)
            report = PlanReportData(
                epoch=epoch,
                cost_kind="cautious",
                criterion="eigenvalues",
                search="cautious",
                horizon=1,
                cost_names=("measurements", "done"),
                predicted_costs=(float(self.cautious.measurements), float(self.cautious.done)),
                evaluations=0,
                wall_time_s=time.perf_counter() - start,
            )
            return Decision(epoch, (command,), report=report)
        if self.mre_positioning or self.selecting:
            return self._decide_mre(epoch, track, snapshots, start)
        if not self.active:
            commands = tuple(Command(pid, epoch, 0.0, 0.0) for pid in self.controllable)
            return Decision(epoch, commands)
        platforms = self._platforms(snapshots)
        belief = self._belief(epoch, track, platforms)
        result = plan(
            platforms, belief, self.settings, F=self.F, Q=self.Q, dt=self.dt, rng=self.rng
        )
        commands = _commands(result, epoch)
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

    # --- Ramdaras: MRE positioning and selection -------------------------------------------

    def _mre_prediction(self, track: TrackSnapshot) -> tuple[np.ndarray, np.ndarray]:
        """x_{k+1|k}, P_{k+1|k} from the track (renewal) or the planner's own recursion."""
        if self.cfg.mode == "open_loop":
            if self._mre_state is None:
                prior = self.scenario.target.prior
                self._mre_state = (np.array(prior.mean, dtype=float), prior.covariance())
            x, P = self._mre_state
        else:
            self._require_pv(track)
            x, P = track.mean, track.cov
        P_pred = self.F @ P @ self.F.T + self.Q
        return self.F @ x, 0.5 * (P_pred + P_pred.T)

    def _decide_mre(self, epoch, track, snapshots, start) -> Decision:
        by_id = {s.platform_id: s for s in snapshots}
        missing = [p.id for p in self.scenario.platforms if p.id not in by_id]
        if missing:
            raise ValueError(f"platform states missing for {missing}")
        x_pred, P_pred = self._mre_prediction(track)
        evaluations = 0
        commands = []
        next_pv = {}
        extra = {"positioning_costs": {}}
        # 1. Positioning (sec. 4): each controllable platform on its own, or a PCRLB plan.
        if self.pcrlb:
            platforms = self._platforms(snapshots)
            belief = self._belief(epoch, track, platforms)
            result = plan(
                platforms, belief, self.settings, F=self.F, Q=self.Q, dt=self.dt, rng=self.rng
            )
            evaluations += result.report.evaluations
            commands.extend(_commands(result, epoch))
            next_pv.update((m.platform_id, m.next_pv) for m in result.manoeuvres)
        for p in self.scenario.platforms:
            snap = by_id[p.id]
            if p.id in next_pv:
                continue
            if p.controllable and self.mre_positioning:
                sensors = tuple(s[2] for s in self.sensors if s[1] == p.id)
                pos = position_platform(
                    snap.pv,
                    snap.heading,
                    snap.speed,
                    PlatformLimits.from_config(p.limits, self.dt),
                    sensors,
                    P_pred,
                    self.F,
                    self.Q,
                    x_pred,
                    self.dt,
                    criterion=self.cfg.criterion,
                    search=self.cfg.search,
                    levels=self.cfg.sector_levels,
                    grid_size=self.cfg.grid_size,
                    divisions=self.cfg.quadrant_divisions,
                    patience=self.cfg.quadrant_patience,
                )
                evaluations += pos.evaluations
                dpsi, v = float(pos.manoeuvre[0]), float(pos.manoeuvre[1])
                commands.append(Command(p.id, epoch, dpsi, v - snap.speed, pos.heading, v))
                next_pv[p.id] = pos.next_pv
                extra["positioning_costs"][p.id] = pos.cost
            else:
                if p.controllable:  # planner enabled only for selection: hold course
                    commands.append(Command(p.id, epoch, 0.0, 0.0))
                pv = np.asarray(snap.pv, dtype=float)
                next_pv[p.id] = pv + self.dt * np.array([pv[1], 0.0, pv[3], 0.0])
        # 2. Selection (sec. 3, eq. 27) among all sensors at their planned positions.
        models = [s[2] for s in self.sensors]
        pvs = np.stack([next_pv[s[1]] for s in self.sensors])
        sel_cfg = self.cfg.selection
        decision_sel = {}
        if self.selecting:
            sel = select_sensors(
                sel_cfg.strategy,
                P_pred,
                self.F,
                self.Q,
                x_pred,
                models,
                pvs,
                criterion=sel_cfg.criterion,
                count=sel_cfg.count,
                fixed=self._fixed_index,
                rng=self.rng,
            )
            evaluations += sel.evaluations
            chosen = sorted(sel.selected)
            label = "trace" if sel_cfg.strategy == "trace" else sel_cfg.criterion
            decision_sel = dict(
                selected_sensor_ids=tuple(self.sensors[i][0] for i in chosen),
                candidate_sensor_ids=tuple(s[0] for s in self.sensors),
                selection_costs=tuple(float(c) for c in sel.costs),
                selection_criterion=f"{sel_cfg.strategy}/{label}",
            )
        else:
            chosen = list(range(len(self.sensors)))
        # 3. What the MRE expects with the chosen sensors (eq. 23), for the report and bound.
        P_upd = expected_update(P_pred, x_pred, [models[i] for i in chosen], pvs[chosen])
        P_hat = self.F @ P_upd @ self.F.T + self.Q
        P_hat = 0.5 * (P_hat + P_hat.T)
        if self.cfg.mode == "open_loop":
            self._mre_state = (x_pred, P_upd)
        criterion = sel_cfg.criterion if self.selecting else self.cfg.criterion
        objective = float(mre_criterion(criterion, P_hat, x_pred))
        extra.update(
            mre_cov=P_hat,
            mre_updated_cov=P_upd,
            planned_pv={k: np.asarray(v, dtype=float) for k, v in next_pv.items()},
        )
        report = PlanReportData(
            epoch=epoch,
            cost_kind="mre",
            criterion=criterion,
            search=self.cfg.search if self.mre_positioning else "none",
            horizon=1,
            cost_names=MRE_REPORT_COSTS,
            predicted_costs=(
                objective,
                float(position_determinant(P_hat)),
                float(trace_cost(P_hat)),
                float(position_determinant(P_upd)),
                float(trace_cost(P_upd)),
            ),
            evaluations=evaluations,
            wall_time_s=time.perf_counter() - start,
        )
        return Decision(epoch, tuple(commands), report=report, extra=extra, **decision_sel)


def _commands(result, epoch: int) -> tuple[Command, ...]:
    """The commands of a PCRLB plan's manoeuvres for the leg epoch -> epoch+1."""
    return tuple(
        Command(m.platform_id, epoch, m.heading_change, m.speed_change, m.heading, m.speed)
        for m in result.manoeuvres
    )
