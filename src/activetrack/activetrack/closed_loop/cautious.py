"""Stop-and-measure control of one robot by the beta-cautious planner (Vander Hook et al.).

Algorithm 1 chooses where the next measurement is taken; this turns its waypoints into
per-epoch commands for the simulator: drive straight at up to v_max, stop on the waypoint,
wait t_m seconds, measure, then ask Algorithm 1 again with the updated estimate.
"""

from __future__ import annotations

import math

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.data import Command, PlatformSnapshot, TrackEstimate
from activetrack.models.sensors import AmbiguousBearingSensor, BearingSensor
from activetrack.planning.cautious import CautiousPlanner
from activetrack.scenarios.build import build_sensor
from activetrack.scenarios.schema import Scenario

_ARRIVED = 1e-6  # m


class CautiousController:
    """Per-epoch commands for the single controllable platform; no randomness."""

    def __init__(self, scenario: Scenario):
        robots = [p for p in scenario.platforms if p.controllable]
        if len(robots) != 1:
            raise ValueError("planner.search 'cautious' needs exactly one controllable platform")
        robot = robots[0]
        sensors = [build_sensor(s) for s in robot.sensors]
        sensor = sensors[0] if len(sensors) == 1 else None
        if not isinstance(sensor, BearingSensor | AmbiguousBearingSensor):
            raise ValueError("planner.search 'cautious' needs one bearing sensor on the robot")
        if robot.limits is None:
            raise ValueError(f"platform {robot.id!r} is controllable but has no limits")
        cfg = scenario.planner.cautious
        self.robot_id = robot.id
        self.dt = scenario.dt
        self.v_max = robot.limits.v_max
        self.dwell_epochs = max(1, math.ceil(float(cfg.t_m) / scenario.dt))
        self.planner = CautiousPlanner(
            sigma_s=sensor.sigma,
            prior_cov=scenario.target.prior.covariance(),
            beta=cfg.beta,
            c_d=cfg.c_d,
            t_m=cfg.t_m,
            r_min=cfg.r_min,
            max_measurements=cfg.max_measurements,
            tail=cfg.tail,
        )
        self.waypoint: np.ndarray | None = None
        self.dwell_left = 0
        self.measurements = 0
        self.awaiting = False  # a measurement was requested for the next epoch
        self.done = False

    def decide(self, epoch: int, track: TrackEstimate, robot: PlatformSnapshot) -> Command:
        position = robot.pv[[0, 2]]
        if self.awaiting:  # the track now holds the measurement taken at this epoch
            self.awaiting = False
            self.measurements += 1
            self.waypoint = None
        if self.waypoint is None and not self.done:
            action = self.planner.next_action(
                track.state, track.state_cov, position, self.measurements
            )
            self.done = action.done
            self.waypoint = None if action.done else np.asarray(action.waypoint, dtype=float)
            self.dwell_left = self.dwell_epochs
        if self.done:
            return self._command(epoch, robot, robot.heading, 0.0, take=False)
        offset = self.waypoint - position
        distance = float(np.hypot(*offset))
        if distance > _ARRIVED:  # drive straight at the waypoint, arriving exactly on it
            heading = math.atan2(offset[1], offset[0])
            return self._command(
                epoch, robot, heading, min(self.v_max, distance / self.dt), take=False
            )
        self.dwell_left -= 1  # stopped on the waypoint; the last dwell epoch ends in a measurement
        take = self.dwell_left <= 0
        self.awaiting = take
        return self._command(epoch, robot, robot.heading, 0.0, take=take)

    def _command(
        self, epoch: int, robot: PlatformSnapshot, heading: float, speed: float, take: bool
    ) -> Command:
        w = self.waypoint
        return Command(
            self.robot_id,
            epoch,
            float(wrap_angle(heading - robot.heading)),
            speed - robot.speed,
            heading,
            speed,
            take_measurement=take,
            waypoint=None if w is None else (float(w[0]), float(w[1])),
        )
