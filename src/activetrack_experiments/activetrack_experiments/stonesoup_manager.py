"""Stone Soup's sensor manager pointing a scenario's steerable beams, as a planner of the closed
loop (issue 25, item 5): ``BruteForceSensorManager`` with its ``UncertaintyRewardFunction``
choosing, each epoch, the joint beam pointing among a pointing at each confirmed track; every
controllable platform holds course (Stone Soup steers none). Our simulator, tracker and
evaluation are used unchanged, so on common random numbers its runs pair with ours.

Stone Soup is a bench-only dependency (``requirements-bench.txt``): it is imported when a
manager is built, never at import of this module (:func:`available` says whether it is there).
The choices made to make its brute force tractable (a listed pointing per track instead of the
uniform dwell grid, the best ``candidates`` per beam kept) are in the docstring of
``benchmarks/multitarget.py`` (part 2), where they were measured.
"""

from __future__ import annotations

import functools
import importlib.util
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.closed_loop.components import target_dynamics
from activetrack.data import (
    BeamCommand,
    Command,
    Decision,
    PlanReportData,
    PlatformSnapshot,
    TrackEstimate,
    TrackSet,
)
from activetrack.models.clutter import ClutteredSensor
from activetrack.scenarios.build import build_sensor
from activetrack.scenarios.schema import Scenario

__all__ = [
    "DEFAULT_CANDIDATES",
    "EPOCH",
    "Pointing",
    "StoneSoupBeamManager",
    "available",
    "beam_pointings",
    "listed_radars",
]

EPOCH = datetime(2024, 1, 1)  # Stone Soup's timestamps: t = 0 of a run
DEFAULT_CANDIDATES = 3  # pointings per beam left to the brute force


def available() -> bool:
    """Whether Stone Soup is installed (``make bench``)."""
    return importlib.util.find_spec("stonesoup") is not None


@functools.cache
def listed_radars() -> tuple[type, type]:
    """Stone Soup's ``RadarRotatingBearingRange`` and ``RadarRotatingBearing`` whose dwell-centre
    actions are the bearings of their ``pointings`` property (rad, world frame: the radars keep
    orientation zero) instead of the uniform ``DwellActionsGenerator`` grid. Defined on first use
    (Stone Soup is bench-only)."""
    from stonesoup.base import Property
    from stonesoup.sensor.action.dwell_action import ChangeDwellAction, DwellActionsGenerator
    from stonesoup.sensor.radar.radar import RadarRotatingBearing, RadarRotatingBearingRange
    from stonesoup.types.angle import Angle

    class ListedDwellActionsGenerator(DwellActionsGenerator):
        """Dwell-centre changes to each of ``bearings``, the shorter way round."""

        bearings: tuple = Property(default=(), doc="Dwell centres offered, rad")

        def __iter__(self):
            start = float(self.initial_value)
            for b in self.bearings:
                target = Angle(start + float(wrap_angle(b - start)))
                end, increasing = self._end_time_direction(target)
                yield ChangeDwellAction(
                    rotation_end_time=end, generator=self, end_time=self.end_time,
                    target_value=target, increasing_angle=increasing,
                )  # fmt: skip

    def listed_actions(self, timestamp, start_timestamp=None):
        generator = ListedDwellActionsGenerator(
            owner=self, attribute="dwell_centre", start_time=start_timestamp or self.timestamp,
            end_time=timestamp, rpm=self.rpm, resolution=self.resolution,
            bearings=tuple(self.pointings),
        )  # fmt: skip
        return {generator}

    class ListedBearingRange(RadarRotatingBearingRange):
        pointings: tuple = Property(default=(), doc="Dwell centres offered, rad")
        actions = listed_actions

    class ListedBearing(RadarRotatingBearing):
        pointings: tuple = Property(default=(), doc="Dwell centres offered, rad")
        actions = listed_actions

    return ListedBearingRange, ListedBearing


@dataclass(frozen=True)
class Pointing:
    """A beam pointed at track ``track`` (index into the confirmed tracks): world ``bearing``
    [rad] and the tracks whose predicted positions it covers (indices)."""

    bearing: float
    track: int
    covered: tuple[int, ...]


def beam_pointings(
    beam_width: float, r_max: float, pv: np.ndarray, X: np.ndarray
) -> list[Pointing]:
    """A pointing at each predicted track position ``X`` ``(T, 4)`` within ``r_max`` of the
    sensor at ``pv`` ``(4,)``; of those covering the same tracks (within +-beam_width / 2, as
    Stone Soup's field-of-view test) only the first is kept: they earn the same reward."""
    dx, dy = X[:, 0] - pv[0], X[:, 2] - pv[2]
    bearing = np.arctan2(dy, dx)
    near = np.hypot(dx, dy) <= r_max
    out: list[Pointing] = []
    seen: set[tuple[int, ...]] = set()
    for t in np.flatnonzero(near):
        inside = near & (np.abs(wrap_angle(bearing - bearing[t])) <= 0.5 * beam_width)
        covered = tuple(int(i) for i in np.flatnonzero(inside))
        if covered not in seen:
            seen.add(covered)
            out.append(Pointing(float(bearing[t]), int(t), covered))
    return out


@dataclass(frozen=True)
class _Beam:
    sensor_id: str
    platform: int  # index into the scenario's platforms
    model: ClutteredSensor
    width: float  # the beam's, rad


class StoneSoupBeamManager:
    """Stone Soup's ``BruteForceSensorManager`` with its ``UncertaintyRewardFunction`` (sum over
    tracks of ||P_pred||_F - ||P_upd||_F, EKF updates, sensors in turn) pointing a scenario's
    steerable beams; every controllable platform holds course. The loop's planner seam
    (``PlannerLike`` of :mod:`activetrack.closed_loop.loop`); ``rng`` is not drawn from.

    Each epoch: our confirmed tracks become Stone Soup ``GaussianState`` tracks at t_k; each
    beam becomes a rotating radar at its platform's hold-course position at t_k+1 (one turn per
    epoch, so every bearing is reachable) offering :func:`beam_pointings` of the tracks' F x;
    when a beam has more than ``candidates`` of them the reward of each alone ranks them and
    the best ``candidates`` stay; ``choose_actions(tracks, t_k+1)`` picks the joint pointing,
    given only the tracks some offered pointing covers (the others add zero to every
    configuration's reward). A beam with no pointing, or every beam with no confirmed track,
    sweeps as :class:`MultiTargetPlanner` does: one beam width on from its last bearing."""

    def __init__(
        self,
        scenario: Scenario,
        rng: np.random.Generator | None = None,
        candidates: int = DEFAULT_CANDIDATES,
    ):
        from stonesoup.models.transition.linear import LinearGaussianTimeInvariantTransitionModel
        from stonesoup.predictor.kalman import KalmanPredictor
        from stonesoup.sensormanager.reward import UncertaintyRewardFunction
        from stonesoup.updater.kalman import ExtendedKalmanUpdater

        if isinstance(candidates, bool) or not isinstance(candidates, int) or candidates < 1:
            raise ValueError(f"candidates: must be an integer >= 1, got {candidates!r}")
        d = target_dynamics(scenario)
        self.F, self.dt, self.candidates = d.F, scenario.dt, candidates
        transition = LinearGaussianTimeInvariantTransitionModel(
            transition_matrix=d.F, covariance_matrix=d.Q
        )
        self.reward = UncertaintyRewardFunction(
            predictor=KalmanPredictor(transition),
            updater=ExtendedKalmanUpdater(measurement_model=None),
            method_sum=True,
        )
        gate = scenario.tracker.tracks.gate_sigmas
        self.beams = tuple(
            _Beam(s.id, i, ClutteredSensor.wrap(build_sensor(s), s, gate), float(s.beam_width))
            for i, p in enumerate(scenario.platforms)
            for s in p.sensors
            if s.beam_width is not None
        )
        self.platform_ids = tuple(p.id for p in scenario.platforms)
        self.controllable = tuple(p.controllable for p in scenario.platforms)
        self.bearing: dict[str, float] = {}  # each beam's last pointing
        self.configurations = 0  # reward evaluations, all epochs

    def decide(
        self, epoch: int, tracks: TrackSet, platforms: Sequence[PlatformSnapshot]
    ) -> Decision:
        """Beam pointings for epoch+1 (module docstring), hold course for every platform."""
        start = time.perf_counter()
        snaps = {s.platform_id: s for s in platforms}
        pv = np.stack([snaps[i].pv for i in self.platform_ids])
        next_pv = pv + self.dt * pv[:, [1, 1, 3, 3]] * np.array([1.0, 0.0, 1.0, 0.0])
        confirmed = tracks.confirmed
        chosen = self._choose(tracks.time, confirmed, next_pv) if confirmed else {}
        beams = []
        for b in self.beams:
            if b.sensor_id in chosen:
                bearing, t = chosen[b.sensor_id]
                track_id = confirmed[t].track_id
            else:
                last = self.bearing.get(b.sensor_id, snaps[self.platform_ids[b.platform]].heading)
                bearing = last + b.width if b.sensor_id in self.bearing else last
                track_id = -1
            self.bearing[b.sensor_id] = float(wrap_angle(bearing))
            beams.append(BeamCommand(b.sensor_id, epoch, self.bearing[b.sensor_id], track_id))
        commands = tuple(
            Command(p, epoch, 0.0, 0.0)
            for p, c in zip(self.platform_ids, self.controllable, strict=True)
            if c
        )
        report = PlanReportData(
            epoch, "uncertainty", "cov_norm_reduction", "brute_force" if chosen else "sweep", 1,
            wall_time_s=time.perf_counter() - start,
        )  # fmt: skip
        assignment = {b.sensor_id: b.track_id for b in beams}
        return Decision(
            epoch, commands, tuple(beams), report=report, extra={"assignment": assignment}
        )

    def _sensor(self, b: _Beam, pv: np.ndarray, offered: list[Pointing], when: datetime):
        """Stone Soup's rotating radar for beam ``b`` at ``pv`` offering ``offered``."""
        from stonesoup.types.angle import Angle
        from stonesoup.types.array import StateVector

        range_bearing, bearing_only = listed_radars()
        m = b.model
        width = b.width
        R = np.atleast_2d(np.asarray(m.R, dtype=float))
        common = dict(
            position_mapping=(0, 2), ndim_state=4, position=StateVector([pv[0], pv[2]]),
            rpm=60.0 / self.dt, fov_angle=width, resolution=Angle(width),
            dwell_centre=StateVector([self.bearing.get(b.sensor_id, 0.0)]),
            max_range=float(m.r_max), pointings=tuple(p.bearing for p in offered),
        )  # fmt: skip
        if m.kind == "range_bearing":  # ours (range, bearing), Stone Soup's (bearing, range)
            sensor = range_bearing(noise_covar=R[::-1, ::-1].copy(), **common)
        else:
            sensor = bearing_only(noise_covar=R, **common)
        sensor.timestamp = when
        return sensor

    def _choose(
        self, time_s: float, confirmed: tuple[TrackEstimate, ...], next_pv: np.ndarray
    ) -> dict[str, tuple[float, int]]:
        """sensor id -> (bearing, confirmed-track index) chosen by the brute force."""
        from stonesoup.sensormanager import BruteForceSensorManager
        from stonesoup.types.array import CovarianceMatrix, StateVector
        from stonesoup.types.state import GaussianState
        from stonesoup.types.track import Track

        now = EPOCH + timedelta(seconds=time_s)
        then = now + timedelta(seconds=self.dt)
        ss_tracks = [
            Track([GaussianState(StateVector(t.mean), CovarianceMatrix(t.cov), timestamp=now)])
            for t in confirmed
        ]
        X = np.stack([t.mean for t in confirmed]) @ self.F.T
        sensors, offered = {}, {}
        for b in self.beams:
            m, pv = b.model, next_pv[b.platform]
            options = beam_pointings(b.width, float(m.r_max), pv, X)
            if len(options) > self.candidates:
                options = self._best(b, pv, options, ss_tracks, now, then)
            if options:
                sensors[b.sensor_id] = self._sensor(b, pv, options, now)
                offered[b.sensor_id] = options
        if not sensors:
            return {}
        covered = sorted({i for opts in offered.values() for p in opts for i in p.covered})
        manager = BruteForceSensorManager(
            sensors=set(sensors.values()), reward_function=self.reward
        )
        config = manager.choose_actions({ss_tracks[i] for i in covered}, then)[0]
        self.configurations += math.prod(len(o) for o in offered.values())
        out = {}
        for sid, sensor in sensors.items():
            target = float(config[sensor][0].target_value)
            k = int(np.argmin([abs(float(wrap_angle(target - p.bearing))) for p in offered[sid]]))
            out[sid] = (offered[sid][k].bearing, offered[sid][k].track)
        return out

    def _best(
        self,
        b: _Beam,
        pv: np.ndarray,
        options: list[Pointing],
        ss_tracks: list,
        now: datetime,
        then: datetime,
    ) -> list[Pointing]:
        """The ``candidates`` pointings of ``b`` with the largest reward alone (ties: first)."""
        sensor = self._sensor(b, pv, options, now)
        (generator,) = sensor.actions(then)
        rewards = [
            self.reward({sensor: (action,)}, {ss_tracks[i] for i in p.covered}, then)
            for action, p in zip(generator, options, strict=True)
        ]
        self.configurations += len(options)
        keep = np.argsort(-np.asarray(rewards, dtype=float), kind="stable")[: self.candidates]
        return [options[i] for i in sorted(keep)]
