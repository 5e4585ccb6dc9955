"""tracker_node: the scenario's filter (EKF, particle filter or a registered one) on the
bearing, polar and generic measurements (activetrack.closed_loop.TrackerCore).

An epoch k is announced by the simulator's platform states of epoch k (one per platform, each
saying how many measurements the sim published at k); the tracker updates once it holds them
all, sorted in scenario order, and publishes the track. Each measurement must agree with its
platform's announced position. An epoch that stays incomplete for ``epoch_timeout`` seconds is
closed with what arrived (warned and counted), like a missing command in the simulator, so
nothing can stall the tracker. In lockstep mode only epoch last + 1 is accepted. Outputs:
``TrackEstimate`` (with the planner's posterior samples for a PF),
``geometry_msgs/PoseWithCovarianceStamped`` and a subsampled particle cloud
(``geometry_msgs/PoseArray``) for standard tools. Bad messages are rejected, counted and logged
(activetrack_ros.node_base); the node keeps running.
"""

import array
import math
import time
from dataclasses import dataclass, field

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import Pose, PoseArray, PoseWithCovarianceStamped
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from activetrack import limits
from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.data import PlatformSnapshot
from activetrack.closed_loop.tracker import TrackerCore, pose_of
from activetrack.filters import filter_names
from activetrack.filters.measurement import Measurement
from activetrack.geometry import covariance_ellipse
from activetrack.scenarios import load_scenario, with_tracker_overrides
from activetrack_ros import graph as topics
from activetrack_ros.convert import MeasurementChecker, header, marker, platform_from_msg
from activetrack_ros.frames import estimate_frame, planar_transform
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import COMMON, ParamSpec
from activetrack_ros.spin import spin_node
from msgs_defs.msg import (
    BearingMeasurement,
    PlatformState,
    PolarMeasurement,
    TrackEstimate,
)
from msgs_defs.msg import (
    Measurement as MeasurementMsg,
)

FREE_WINDOW = 64  # free mode: epochs ahead of the last update that may be collected at once
POSITION_TOLERANCE = 1e-6  # m between a measurement's sensor position and its platform state


@dataclass
class OpenEpoch:
    """What has arrived for one epoch that is not processed yet."""

    opened: float  # time.monotonic() of the first message
    measurements: dict[str, Measurement] = field(default_factory=dict)
    states: dict[str, PlatformSnapshot] = field(default_factory=dict)
    announced: dict[str, int] = field(default_factory=dict)  # platform id -> measurement count


PARAMS = (
    *COMMON,
    ParamSpec(
        "cloud_size", 100, "particles in the published cloud (changeable while running)",
        read_only=False, low=0, high=100_000,
    ),
    ParamSpec(
        "particles", 0, "particle filter size (0: the scenario's)", low=0,
        high=limits.MAX_PARTICLES,
    ),
    ParamSpec(
        "epoch_timeout", 5.0,
        "wall seconds before an incomplete epoch is closed with what arrived (changeable)",
        read_only=False, low=1e-3, high=3600.0,
    ),
)  # fmt: skip
# Checked once the scenario's plugins (which may register filters) are imported.
FILTER = ParamSpec(
    "filter", "", "a registered filter name (empty: the scenario's)", choices=filter_names
)


class TrackerNode(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("tracker_node", **kwargs)
        changes = {"cloud_size": self._set_cloud_size, "epoch_timeout": self._set_epoch_timeout}
        p = self.declare_params(PARAMS, changes, last=False)
        scenario = load_scenario(p["scenario"])  # imports its plugins: their filters too
        filter_name = self.declare_params((FILTER,), changes)["filter"]
        self.scenario = with_tracker_overrides(
            scenario, filter=filter_name or None, particles=p["particles"] or None
        )
        self.use_scenario(self.scenario)
        self.mode = p["mode"]
        self.epoch_timeout = p["epoch_timeout"]
        self.cloud_size = p["cloud_size"]
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[1]
        self.core = TrackerCore(self.scenario, rng)
        # Scenario order of the sensors: measurements of an epoch are applied in this order.
        self.sensor_order = {sid: i for i, sid in enumerate(self.core.sensors)}
        self.platform_ids = {p.id for p in self.scenario.platforms}
        owner = {s.id: p.id for p in self.scenario.platforms for s in p.sensors}
        self.check = MeasurementChecker(self.scenario, self.core.sensors, owner)
        self.owner = owner
        self.epochs: dict[int, OpenEpoch] = {}
        self.last_epoch = 0

        self.track_pub = self.publisher(TrackEstimate, topics.TRACK)
        self.pose_pub = self.publisher(PoseWithCovarianceStamped, topics.TRACK_POSE)
        self.cloud_pub = self.publisher(PoseArray, topics.PARTICLES)
        self.diag_pub = self.publisher(DiagnosticArray, topics.DIAGNOSTICS)
        self.marker_pub = self.publisher(MarkerArray, topics.MARKERS)
        self.tf_pub = self.publisher(TFMessage, topics.TF)
        self.subscribe(BearingMeasurement, topics.BEARING_MEASUREMENTS, self.on_bearing)
        self.subscribe(PolarMeasurement, topics.POLAR_MEASUREMENTS, self.on_polar)
        self.subscribe(MeasurementMsg, topics.MEASUREMENTS, self.on_measurement)
        self.subscribe(PlatformState, topics.PLATFORM_STATES, self.on_platform)
        self.guarded_timer(0.05, self.on_tick)
        self.prior_views = self.core.snapshot()  # epoch 0: the prior
        self.publish_estimate(self.prior_views)

    def _set_cloud_size(self, size: int) -> None:
        self.cloud_size = size

    def _set_epoch_timeout(self, seconds: float) -> None:
        self.epoch_timeout = seconds

    # --- inputs --------------------------------------------------------------------------

    def on_bearing(self, msg: BearingMeasurement) -> None:
        self.add_measurement(msg.epoch, self.check.bearing(msg))

    def on_polar(self, msg: PolarMeasurement) -> None:
        self.add_measurement(msg.epoch, self.check.polar(msg))

    def on_measurement(self, msg: MeasurementMsg) -> None:
        self.add_measurement(msg.epoch, self.check.generic(msg))

    def on_platform(self, msg: PlatformState) -> None:
        snap = platform_from_msg(msg, self.scenario, self.platform_ids)
        if self.prior_views is not None:
            # The prior's views (tf, pose, particles, markers: volatile) go out with the sim's
            # epoch 0, not at start-up, when no reader in another process has matched them
            # yet (a viewer that --wait-for held the run for would miss them).
            prior, self.prior_views = self.prior_views, None
            self.publish_views(prior)
        if snap.epoch <= self.last_epoch:
            return self.ignore("old_epoch")  # epoch 0, or history replayed to a late joiner
        epoch = self.open_epoch(snap.epoch, "platform state")
        if snap.platform_id in epoch.states:
            raise Rejected("duplicate", f"second state of {snap.platform_id!r} at {snap.epoch}")
        epoch.states[snap.platform_id] = snap
        epoch.announced[snap.platform_id] = msg.epoch_measurement_count
        self.close_ready()

    def add_measurement(self, k: int, m: Measurement) -> None:
        epoch = self.open_epoch(k, f"measurement of {m.sensor_id!r}")
        if m.sensor_id in epoch.measurements:
            raise Rejected("duplicate", f"second measurement of {m.sensor_id!r} at {k}")
        epoch.measurements[m.sensor_id] = m
        self.close_ready()

    def open_epoch(self, k: int, what: str) -> OpenEpoch:
        if k <= self.last_epoch:
            raise Rejected("out_of_order", f"{what} for epoch {k} <= last update {self.last_epoch}")
        ahead = 1 if self.mode == "lockstep" else FREE_WINDOW
        if k > self.last_epoch + ahead:
            raise Rejected("future_epoch", f"{what} for epoch {k} > {self.last_epoch} + {ahead}")
        if k not in self.epochs:
            self.epochs[k] = OpenEpoch(time.monotonic())
        return self.epochs[k]

    # --- epochs --------------------------------------------------------------------------

    def complete(self, epoch: OpenEpoch) -> bool:
        """Every platform announced the epoch and every announced measurement is here."""
        if epoch.states.keys() != self.platform_ids:
            return False
        return len(epoch.measurements) >= max(epoch.announced.values())

    def close_ready(self) -> None:
        """Process complete epochs in order; in free mode a complete later epoch also closes
        the incomplete ones before it (their missing messages are late or lost)."""
        while self.epochs:
            complete = [k for k in sorted(self.epochs) if self.complete(self.epochs[k])]
            if not complete:
                return
            for k in sorted(e for e in self.epochs if e < complete[0]):
                self.process(k, complete=False)
            self.process(complete[0], complete=True)

    def on_tick(self) -> None:
        """An epoch incomplete for epoch_timeout seconds is closed with what arrived."""
        if not self.epochs:
            return
        k = min(self.epochs)
        waited = time.monotonic() - self.epochs[k].opened
        if waited >= self.epoch_timeout:
            self.process(k, complete=False)
            self.close_ready()

    def process(self, k: int, complete: bool) -> None:
        epoch = self.epochs.pop(k)
        if not complete:
            what = f"{len(epoch.measurements)} measurements, states of {sorted(epoch.states)}"
            note_incomplete(self, k, epoch.opened, what)
        ordered = sorted(epoch.measurements.values(), key=lambda m: self.sensor_order[m.sensor_id])
        used = where_their_platforms_are(
            self, k, ordered, epoch.states, lambda m: m.sensor_state, self.owner.__getitem__
        )
        snapshot = self.core.step(k, k * self.scenario.dt, used)
        self.last_epoch = k
        for e in [e for e in self.epochs if e <= k]:
            del self.epochs[e]
        self.counters.count("updates")
        self.counters.count("missed_detections", sum(m.z is None for m in used))
        if not used:
            self.counters.count("epochs_without_measurements")
        self.publish_track(snapshot)

    # --- outputs -------------------------------------------------------------------------

    def publish_track(self, snap) -> None:
        """The track (latched) and its views."""
        self.publish_estimate(snap)
        self.publish_views(snap)

    def publish_estimate(self, snap) -> None:
        """The track message (latched, per epoch: what the planner and evaluator read)."""
        hdr = header(snap.epoch * self.scenario.dt, self.frame_id)
        samples = snap.samples
        self.track_pub.publish(
            TrackEstimate(
                header=hdr,
                target_id=self.scenario.target.id,
                epoch=snap.epoch,
                filter_kind=snap.filter_kind,
                motion_model=snap.motion_model,
                state_names=list(snap.state_names),
                state=[float(v) for v in snap.mean],
                covariance=[float(v) for v in snap.cov.ravel()],
                update_count=snap.update_count,
                missed_detections=snap.missed_detections,
                nis=float(snap.nis),
                ess=float(snap.ess),
                particle_count=snap.particle_count,
                # array('d') from the raw buffer: a 10,000 x 4 list would cost ~25 ms per epoch.
                particle_samples=array.array("d")
                if samples is None
                else array.array("d", np.ascontiguousarray(samples, dtype=float).tobytes()),
                sample_count=0 if samples is None else len(samples),
            )
        )

    def publish_views(self, snap) -> None:
        """What tools show of a track: pose, tf, 2-sigma ellipse, particles, diagnostics."""
        hdr = header(snap.epoch * self.scenario.dt, self.frame_id)
        samples = snap.samples
        x, y, course, P_xy = pose_of(snap, self.core.model)
        pose = PoseWithCovarianceStamped(header=hdr)
        pose.pose.pose.position.x, pose.pose.pose.position.y = x, y
        pose.pose.pose.orientation.z = math.sin(course / 2)
        pose.pose.pose.orientation.w = math.cos(course / 2)
        cov6 = [0.0] * 36  # (x, y, z, roll, pitch, yaw), row-major
        cov6[0], cov6[1], cov6[6], cov6[7] = (float(v) for v in P_xy.ravel())
        pose.pose.covariance = cov6
        self.pose_pub.publish(pose)
        target = estimate_frame(self.scenario.target.id)
        self.tf_pub.publish(TFMessage(transforms=[planar_transform(hdr, target, x, y, course)]))
        # 2-sigma position ellipse of the track.
        points = covariance_ellipse((x, y), P_xy, 2.0)
        ellipse = marker(hdr, "track", 0, Marker.LINE_STRIP, (0.9, 0.1, 0.1, 1.0), points)
        ellipse.scale.x = 5.0  # line width, m
        self.marker_pub.publish(MarkerArray(markers=[ellipse]))
        if samples is not None and self.cloud_size > 0:
            step = max(1, len(samples) // self.cloud_size)
            cloud = PoseArray(header=hdr)
            for x in self.core.model.kinematics(samples[::step]):
                p = Pose()
                p.position.x, p.position.y = float(x[0]), float(x[2])
                cloud.poses.append(p)
            self.cloud_pub.publish(cloud)
        message = f"epoch {snap.epoch} {snap.filter_kind}: ESS {snap.ess:.0f} NIS {snap.nis:.2f}"
        self.diag_pub.publish(
            self.diagnostics_array(hdr, "activetrack/tracker_node", self.scenario.name, message)
        )


def where_their_platforms_are(node, k: int, items, states, sensor_pv, owner) -> list:
    """The epoch's ``items`` (measurements or scans) whose sensor position ``sensor_pv(item)``
    is its platform's announced one (``states``: platform id -> state; ``owner``: sensor id
    -> platform id); each other one is rejected (counted and logged) as inconsistent."""
    kept = []
    for item in items:
        state = states.get(owner(item.sensor_id))
        if state is not None and not np.allclose(
            sensor_pv(item), state.pv, rtol=0, atol=POSITION_TOLERANCE
        ):
            node.reject("inconsistent", f"{item.sensor_id!r} at {k} is not where its platform is")
            continue
        kept.append(item)
    return kept


def note_incomplete(node, k: int, opened: float, what: str) -> None:
    """An epoch closed before all it announced arrived: counted and logged (rate-limited)."""
    node.counters.count("incomplete_epochs")
    node.log_limited(
        "warning",
        "incomplete",
        f"epoch {k} closed incomplete after {time.monotonic() - opened:.2f} s: {what}",
    )


def main(args=None):
    spin_node(TrackerNode, args)


if __name__ == "__main__":
    main()
