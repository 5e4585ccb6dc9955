"""tracker_node: the scenario's tracker (activetrack.tracking.Tracker) on the sim's scans.

The ``scenario`` parameter names a scenario file or a tracker-only configuration
(docs/track-your-data.md): with the latter the node tracks scans from anywhere, e.g. in free
mode those ``activetrack play`` publishes from a bag ``activetrack track`` wrote.

Epoch k is announced by its platform states (each saying how many scans the sim published);
the tracker updates once it holds them all and every scan, each where its platform's state
says, and publishes every live track (with the planner's posterior samples for a particle
filter). Epochs are processed in order; messages of up to BUFFER_EPOCHS epochs ahead of the
last update are kept until their turn (a message of a later epoch is refused, counted). An
epoch incomplete for ``epoch_timeout`` seconds, or when a later epoch is complete (the sim went
on without it), is closed with what arrived (warned, counted, and recorded per epoch as
``timeout.<k>.*``), so nothing can stall the tracker (docs/robustness.md, "Lockstep"). A JPDA
cluster too large for its exact hypothesis net under ``tracker.tracks.oversize_cluster: error``
leaves its epoch untracked: counted (``association.oversize_epochs``), logged with the way out,
reported on /diagnostics, and the node goes on with the next epoch; under ``prune`` the
tracker's ``association.pruned_clusters`` and ``association.dropped_pairs`` are the node's
counters too (the run's summary prints them).
For standard tools: each confirmed track's pose with covariance, tf frame, 2-sigma ellipse
and id label, and a subsampled particle cloud.
"""

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np
from geometry_msgs.msg import Point, Pose, PoseArray, PoseWithCovarianceStamped
from tf2_msgs.msg import TFMessage
from visualization_msgs.msg import Marker, MarkerArray

from activetrack import limits
from activetrack.closed_loop.components import build_tracker, component_rngs, scene_sensors
from activetrack.data import PlatformSnapshot, Scan, TrackSet
from activetrack.filters import filter_names
from activetrack.filters.jpda import NetOversize
from activetrack.geometry import covariance_ellipse
from activetrack.scenarios import load_tracking, with_tracker_overrides
from activetrack_ros import graph as topics
from activetrack_ros.convert import (
    header,
    marker,
    platform_from_msg,
    scan_from_msg,
    track_array_msg,
)
from activetrack_ros.frames import estimate_frame, planar_transform
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import COMMON, SCENARIO, ParamSpec
from activetrack_ros.spin import spin_node
from msgs_defs.msg import PlatformState, TrackArray
from msgs_defs.msg import Scan as ScanMsg

# Epochs ahead of the last update whose messages are kept (either mode): in lockstep a tracker
# behind the sim (an epoch waiting for a late message) catches up from them.
BUFFER_EPOCHS = 64
POSITION_TOLERANCE = 1e-6  # m between a scan's sensor position and its platform state
CONFIRMED_RGBA = (0.9, 0.1, 0.1, 1.0)
_XY = np.ix_([0, 2], [0, 2])


@dataclass
class OpenEpoch:
    """What has arrived for one epoch that is not processed yet."""

    opened: float  # time.monotonic() of the first message
    scans: dict[str, Scan] = field(default_factory=dict)
    states: dict[str, PlatformSnapshot] = field(default_factory=dict)
    announced: int = 0  # scans the sim published at the epoch


TRACKED = replace(
    SCENARIO,
    description="scenario or tracker configuration YAML file (checked on load: docs in README, "
    "docs/track-your-data.md)",
)
PARAMS = (
    *(TRACKED if spec is SCENARIO else spec for spec in COMMON),
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


def track_frame(track) -> str:
    """Its target's estimate frame for a track from a prior, else ``target/track<id>/...``."""
    return estimate_frame(track.origin or f"track{track.track_id}")


class TrackerNode(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("tracker_node", **kwargs)
        changes = {
            "cloud_size": self.setter("cloud_size"),
            "epoch_timeout": self.setter("epoch_timeout"),
        }
        p = self.declare_params(PARAMS, changes, last=False)
        # A tracker configuration, or a scenario's; imports its plugins: their filters too.
        config = load_tracking(p["scenario"])
        filter_name = self.declare_params((FILTER,), changes)["filter"]
        overrides = {"filter": filter_name or None, "particles": p["particles"] or None}
        self.use_scenario(with_tracker_overrides(config, **overrides))
        self.epoch_timeout = p["epoch_timeout"]
        self.cloud_size = p["cloud_size"]
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[1]
        self.core = build_tracker(self.scenario, rng)
        self.sensors = scene_sensors(self.scenario)
        # Scenario order of the sensors: scans of an epoch are applied in this order.
        self.sensor_order = {sid: i for i, sid in enumerate(self.sensors)}
        self.platform_ids = {p.id for p in self.scenario.platforms}
        self.epochs: dict[int, OpenEpoch] = {}
        self.last_epoch = 0
        self.drawn: set[int] = set()  # track ids with markers up
        self.track_views: dict[int, tuple[Marker, Marker]] = {}  # id -> ellipse, label

        self.tracks_pub = self.publisher(TrackArray, topics.TRACKS)
        self.pose_pub = self.publisher(PoseWithCovarianceStamped, topics.TRACK_POSE)
        self.cloud_pub = self.publisher(PoseArray, topics.PARTICLES)
        self.marker_pub = self.publisher(MarkerArray, topics.MARKERS)
        self.tf_pub = self.publisher(TFMessage, topics.TF)
        self.subscribe(ScanMsg, topics.SCANS, self.on_scan)
        self.subscribe(PlatformState, topics.PLATFORM_STATES, self.on_platform)
        self.guarded_timer(0.05, self.on_tick)
        # Epoch 0, the priors' tracks: the track array now (latched), its views (tf, pose,
        # particles, markers: volatile) with the sim's epoch 0 (on_platform), when readers in
        # other processes (a viewer the run waited for) have matched them.
        prior = self.core.snapshot()
        self.prior_views = (prior, self.publish_estimate(prior))

    def on_scan(self, msg: ScanMsg) -> None:
        scan = scan_from_msg(msg, self.scenario, self.sensors)
        epoch = self.open_epoch(scan.epoch, f"scan of {scan.sensor_id!r}")
        if scan.sensor_id in epoch.scans:
            raise Rejected("duplicate", f"second scan of {scan.sensor_id!r} at {scan.epoch}")
        epoch.scans[scan.sensor_id] = scan
        self.close_ready()

    def on_platform(self, msg: PlatformState) -> None:
        snap = platform_from_msg(msg, self.scenario, self.platform_ids)
        if self.prior_views is not None:  # the sim's epoch 0 (__init__)
            prior, self.prior_views = self.prior_views, None
            self.publish_views(*prior)
        if snap.epoch <= self.last_epoch:
            return self.ignore("old_epoch")  # epoch 0, or history replayed to a late joiner
        epoch = self.open_epoch(snap.epoch, "platform state")
        if snap.platform_id in epoch.states:
            raise Rejected("duplicate", f"second state of {snap.platform_id!r} at {snap.epoch}")
        epoch.states[snap.platform_id] = snap
        epoch.announced = max(epoch.announced, msg.epoch_scan_count)
        self.close_ready()

    def open_epoch(self, k: int, what: str) -> OpenEpoch:
        if k <= self.last_epoch:
            raise Rejected("out_of_order", f"{what} for epoch {k} <= last update {self.last_epoch}")
        if k > self.last_epoch + BUFFER_EPOCHS:
            raise Rejected(
                "future_epoch", f"{what} for epoch {k} > {self.last_epoch} + {BUFFER_EPOCHS}"
            )
        if k not in self.epochs:
            self.epochs[k] = OpenEpoch(time.monotonic())
        return self.epochs[k]

    def complete(self, epoch: OpenEpoch) -> bool:
        """Every platform announced the epoch and every announced scan is here."""
        return epoch.states.keys() == self.platform_ids and len(epoch.scans) >= epoch.announced

    def close_ready(self) -> None:
        """Process complete epochs in order; a complete later epoch also closes the incomplete
        ones before it (their missing messages are late or lost: in lockstep the sim published
        the later epoch only once it gave up waiting for this tracker)."""
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
        if time.monotonic() - self.epochs[k].opened >= self.epoch_timeout:
            self.process(k, complete=False)
            self.close_ready()

    def process(self, k: int, complete: bool) -> None:
        epoch = self.epochs.pop(k)
        if not complete:
            self.counters.count("incomplete_epochs")
            self.record_gap(k, epoch)
            self.log_limited(
                "warning",
                "incomplete",
                f"epoch {k} closed incomplete after {time.monotonic() - epoch.opened:.2f} s: "
                f"{len(epoch.scans)} scans, states of {sorted(epoch.states)}",
            )
        used = []
        for scan in sorted(epoch.scans.values(), key=lambda s: self.sensor_order[s.sensor_id]):
            state = epoch.states.get(self.sensors[scan.sensor_id][0])
            pv = scan.sensor_pv if state is None else state.pv  # where its platform says it is
            if np.allclose(scan.sensor_pv, pv, rtol=0, atol=POSITION_TOLERANCE):
                used.append(scan)
            else:
                where = f"{scan.sensor_id!r} at {k} is not where its platform is"
                self.reject_taken("Scan", "inconsistent", where)
        try:
            tracks = self.core.step(k, k * self.scenario.dt, used)
        except NetOversize as e:  # oversize_cluster: error (the message names the way out)
            return self.untracked(k, e)
        self.close_epoch(k)
        for name, value in self.core.association_counters.items():
            if value != self.counters.counts[name]:  # the tracker's running totals, as ours
                self.counters.count(name, value - self.counters.counts[name])
        self.counters.count("updates")
        self.counters.count("detections", tracks.detections)
        self.counters.count("empty_scans", sum(len(s.Z) == 0 for s in used))
        if not used:
            self.counters.count("epochs_without_scans")
        self.publish_tracks(tracks)

    def close_epoch(self, k: int) -> None:
        """Epoch k is done: its messages, and any of earlier epochs, are old from now on."""
        self.last_epoch = k
        for e in [e for e in self.epochs if e <= k]:
            del self.epochs[e]

    def untracked(self, k: int, error: NetOversize) -> None:
        """Epoch k's step stopped at a JPDA cluster too large for exact association: the
        epoch is closed without a track array, counted, logged and on /diagnostics (the
        tracker keeps the scans it had applied and steps on with the next epoch)."""
        self.close_epoch(k)
        self.counters.count("association.oversize_epochs")
        self.log_limited("error", "association.oversize", f"epoch {k} not tracked: {error}")
        self.publish_diagnostics(
            header(k * self.scenario.dt, self.frame_id),
            f"epoch {k} not tracked: a JPDA cluster of {error.tracks} tracks is too large for "
            f"exact association (tracker.tracks.oversize_cluster: {self.core.oversize})",
        )

    def record_gap(self, k: int, epoch: OpenEpoch) -> None:
        """What epoch k was closed without, for the run's summary (``timeout.<k>.*``)."""
        self.counters.count(f"timeout.{k}.closed_incomplete")
        states = len(self.platform_ids - epoch.states.keys())
        if states:
            self.counters.count(f"timeout.{k}.missing_states", states)
        scans = epoch.announced - len(epoch.scans)
        if scans > 0:  # (the count is known only from the states that came)
            self.counters.count(f"timeout.{k}.missing_scans", scans)

    def publish_tracks(self, tracks: TrackSet) -> None:
        """The track array (latched) and its views."""
        self.publish_views(tracks, self.publish_estimate(tracks))

    def publish_estimate(self, tracks: TrackSet):
        """Publish the track array (latched: what the planner and evaluator read); its header."""
        msg = track_array_msg(tracks, self.frame_id)
        self.tracks_pub.publish(msg)
        return msg.header

    def publish_views(self, tracks: TrackSet, hdr) -> None:
        """What tools show of the tracks: pose, tf, ellipses and ids, particles, diagnostics.
        A view is built only while its topic has a reader (a viewer, the bag recorder): the
        views are volatile, and at 30 tracks they take 10 ms an epoch (a fifth of a 30-target
        run without a bag). They show the tracker's estimate: its reported tracks."""
        shown = tracks.reported
        poses, frames = self.pose_pub.has_readers(), self.tf_pub.has_readers()
        if poses or frames:
            transforms = []
            for t in shown:
                xy = np.asarray(t.mean)[[0, 2]]
                course = math.atan2(t.mean[3], t.mean[1])
                if poses:
                    self.pose_pub.publish(_pose(hdr, xy, course, np.asarray(t.cov)[_XY]))
                transforms.append(planar_transform(hdr, track_frame(t), xy[0], xy[1], course))
            if frames and transforms:
                self.tf_pub.publish(TFMessage(transforms=transforms))
        now = {t.track_id for t in shown}
        if self.marker_pub.has_readers():
            self.marker_pub.publish(MarkerArray(markers=self.track_markers(hdr, shown, now)))
        self.drawn = now  # (without a reader too: one that joins later saw none of them)
        for gone in self.track_views.keys() - now:
            del self.track_views[gone]
        if self.cloud_pub.has_readers():
            self.publish_cloud(hdr, tracks)
        ess = [t.ess for t in tracks.tracks if not math.isnan(t.ess)]
        confirmed = len(tracks.confirmed)
        withheld = confirmed - len(shown)
        message = (
            f"epoch {tracks.epoch} {tracks.filter_kind}: {confirmed} confirmed of "
            f"{len(tracks.tracks)} tracks, {tracks.detections} detections"
            + (f", {withheld} withheld from the estimate" if withheld else "")
            + (f", lowest ESS {min(ess):.0f}" if ess else "")
        )
        self.publish_diagnostics(hdr, message)

    def track_markers(self, hdr, confirmed, now: set[int]) -> list[Marker]:
        """Each confirmed track's 2-sigma ellipse and id label; DELETEs for those drawn before
        that are gone or no longer confirmed. A track's two markers are built once and
        updated in place each epoch (publishing serialises them): new Marker and Point
        objects were two thirds of the markers' time."""
        markers = []
        for t in confirmed:
            xy = np.asarray(t.mean)[[0, 2]]
            points = covariance_ellipse(xy, np.asarray(t.cov)[_XY], 2.0).tolist()
            ellipse, label = self.track_views.get(t.track_id) or self._track_view(t.track_id)
            ellipse.header = label.header = hdr
            if len(ellipse.points) == len(points):
                for point, (x, y) in zip(ellipse.points, points, strict=True):
                    point.x, point.y = x, y
            else:
                ellipse.points = [Point(x=x, y=y) for x, y in points]
            label.pose.position.x, label.pose.position.y = float(xy[0]), float(xy[1])
            markers += [ellipse, label]
        for gone in sorted(self.drawn - now):
            for ns in ("tracks", "track_ids"):
                m = marker(hdr, ns, gone, Marker.LINE_STRIP, CONFIRMED_RGBA)
                m.action = Marker.DELETE
                markers.append(m)
        return markers

    def _track_view(self, track_id: int) -> tuple[Marker, Marker]:
        """A track's ellipse (no points yet) and id label, kept in ``track_views`` (each epoch
        gives them its header)."""
        hdr = header(0.0, self.frame_id)
        ellipse = marker(hdr, "tracks", track_id, Marker.LINE_STRIP, CONFIRMED_RGBA)
        ellipse.scale.x = 5.0  # line width, m
        label = marker(hdr, "track_ids", track_id, Marker.TEXT_VIEW_FACING, CONFIRMED_RGBA)
        label.scale.z = 50.0  # text height, m
        label.text = str(track_id)
        self.track_views[track_id] = (ellipse, label)
        return ellipse, label

    def publish_cloud(self, hdr, tracks: TrackSet) -> None:
        """The particle tracks' posterior samples, subsampled to about ``cloud_size`` each."""
        clouds = [t.samples for t in tracks.tracks if t.samples is not None]
        if not clouds or self.cloud_size <= 0:
            return
        cloud = PoseArray(header=hdr)
        for samples in clouds:
            step = max(1, len(samples) // self.cloud_size)
            kinematics = self.core.model.kinematics(samples[::step])
            cloud.poses += [Pose(position=Point(x=float(x[0]), y=float(x[2]))) for x in kinematics]
        self.cloud_pub.publish(cloud)


def _pose(hdr, xy, course: float, P_xy) -> PoseWithCovarianceStamped:
    """A track's position with its covariance, heading along its velocity."""
    pose = PoseWithCovarianceStamped(header=hdr)
    pose.pose.pose.position.x, pose.pose.pose.position.y = float(xy[0]), float(xy[1])
    pose.pose.pose.orientation.z = math.sin(course / 2)
    pose.pose.pose.orientation.w = math.cos(course / 2)
    cov6 = [0.0] * 36  # (x, y, z, roll, pitch, yaw), row-major
    cov6[0], cov6[1], cov6[6], cov6[7] = (float(v) for v in np.ravel(P_xy))
    pose.pose.covariance = cov6
    return pose


def main(args=None):
    spin_node(TrackerNode, args)
