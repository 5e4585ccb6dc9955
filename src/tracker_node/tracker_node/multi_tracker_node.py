"""multi_tracker_node: the multi-target tracker (JPDA-EKF or clutter-aware particle filters,
M-of-N track management: activetrack.multitarget.MultiTargetTracker) on the sim's scans.

An epoch k is announced by the simulator's platform states of epoch k (one per platform, each
saying how many scans the sim published at k); the tracker updates once it holds them all,
sorted in scenario order, and publishes every live track with its id and covariance
(``TrackArray``), plus a 2-sigma ellipse and an id label per confirmed track for standard
tools (``MarkerArray``). Each scan must agree with its platform's announced position. An epoch
still incomplete after ``epoch_timeout`` seconds is closed with what arrived (warned and
counted). Lockstep only: just epoch last + 1 is accepted. Bad scans (NaN, unknown sensor,
wrong epoch, a field of view that is not the sensor's) are rejected, counted and logged
(activetrack_ros.node_base); the node keeps running.
"""

import time
from dataclasses import dataclass, field

import numpy as np
from diagnostic_msgs.msg import DiagnosticArray
from visualization_msgs.msg import Marker, MarkerArray

from activetrack.closed_loop.batch import component_rngs
from activetrack.closed_loop.data import PlatformSnapshot
from activetrack.geometry import covariance_ellipse
from activetrack.multitarget.data import Scan, TrackSet
from activetrack.multitarget.tracker import MultiTargetTracker
from activetrack.scenarios import load_scenario
from activetrack_ros import graph as topics
from activetrack_ros.convert import marker, platform_from_msg
from activetrack_ros.convert_multi import scan_from_msg, scan_sensors, track_array_msg
from activetrack_ros.node_base import GraphNode, Rejected
from activetrack_ros.params import COMMON
from activetrack_ros.spin import spin_node
from msgs_defs.msg import PlatformState, TrackArray
from msgs_defs.msg import Scan as ScanMsg
from tracker_node.tracker_node import PARAMS, note_incomplete, where_their_platforms_are

MULTI_PARAMS = (*COMMON, *(p for p in PARAMS if p.name == "epoch_timeout"))
CONFIRMED_RGBA = (0.9, 0.1, 0.1, 1.0)


@dataclass
class OpenEpoch:
    """What has arrived for one epoch that is not processed yet."""

    opened: float  # time.monotonic() of the first message
    scans: dict[str, Scan] = field(default_factory=dict)
    states: dict[str, PlatformSnapshot] = field(default_factory=dict)
    announced: int = 0  # scans the sim published at the epoch


class MultiTrackerNode(GraphNode):
    def __init__(self, **kwargs):
        super().__init__("multi_tracker_node", **kwargs)
        p = self.declare_params(MULTI_PARAMS, {"epoch_timeout": self._set_epoch_timeout})
        self.scenario = load_scenario(p["scenario"])
        self.use_scenario(self.scenario, multi_target=True, mode=p["mode"])
        self.epoch_timeout = p["epoch_timeout"]
        rng = component_rngs(self.scenario.seed, None if p["run"] < 0 else p["run"])[1]
        self.core = MultiTargetTracker(self.scenario, rng)
        self.sensors = scan_sensors(self.scenario)
        self.sensor_order = {sid: i for i, sid in enumerate(self.sensors)}
        self.platform_ids = {p.id for p in self.scenario.platforms}
        self.epochs: dict[int, OpenEpoch] = {}
        self.last_epoch = 0
        self.drawn: set[int] = set()  # track ids with markers up

        self.tracks_pub = self.publisher(TrackArray, topics.TRACKS)
        self.diag_pub = self.publisher(DiagnosticArray, topics.DIAGNOSTICS)
        self.marker_pub = self.publisher(MarkerArray, topics.MARKERS)
        self.subscribe(ScanMsg, topics.SCANS, self.on_scan)
        self.subscribe(PlatformState, topics.PLATFORM_STATES, self.on_platform)
        self.guarded_timer(0.05, self.on_tick)
        self.publish_tracks(self.core.snapshot())  # epoch 0: the priors' tracks

    def _set_epoch_timeout(self, seconds: float) -> None:
        self.epoch_timeout = seconds

    # --- inputs --------------------------------------------------------------------------

    def on_scan(self, msg: ScanMsg) -> None:
        scan = scan_from_msg(msg, self.scenario, self.sensors)
        epoch = self.open_epoch(scan.epoch, f"scan of {scan.sensor_id!r}")
        if scan.sensor_id in epoch.scans:
            raise Rejected("duplicate", f"second scan of {scan.sensor_id!r} at {scan.epoch}")
        epoch.scans[scan.sensor_id] = scan
        self.close_ready()

    def on_platform(self, msg: PlatformState) -> None:
        snap = platform_from_msg(msg, self.scenario, self.platform_ids)
        if snap.epoch <= self.last_epoch:
            return self.ignore("old_epoch")  # epoch 0, or history replayed to a late joiner
        epoch = self.open_epoch(snap.epoch, "platform state")
        if snap.platform_id in epoch.states:
            raise Rejected("duplicate", f"second state of {snap.platform_id!r} at {snap.epoch}")
        epoch.states[snap.platform_id] = snap
        epoch.announced = max(epoch.announced, msg.epoch_measurement_count)
        self.close_ready()

    def open_epoch(self, k: int, what: str) -> OpenEpoch:
        if k <= self.last_epoch:
            raise Rejected("out_of_order", f"{what} for epoch {k} <= last update {self.last_epoch}")
        if k > self.last_epoch + 1:
            raise Rejected("future_epoch", f"{what} for epoch {k} > {self.last_epoch} + 1")
        if k not in self.epochs:
            self.epochs[k] = OpenEpoch(time.monotonic())
        return self.epochs[k]

    # --- epochs --------------------------------------------------------------------------

    def complete(self, epoch: OpenEpoch) -> bool:
        """Every platform announced the epoch and every announced scan is here."""
        return epoch.states.keys() == self.platform_ids and len(epoch.scans) >= epoch.announced

    def close_ready(self) -> None:
        k = self.last_epoch + 1
        if k in self.epochs and self.complete(self.epochs[k]):
            self.process(k, complete=True)

    def on_tick(self) -> None:
        """An epoch incomplete for epoch_timeout seconds is closed with what arrived."""
        k = self.last_epoch + 1
        if k in self.epochs and time.monotonic() - self.epochs[k].opened >= self.epoch_timeout:
            self.process(k, complete=False)

    def process(self, k: int, complete: bool) -> None:
        epoch = self.epochs.pop(k)
        if not complete:
            what = f"{len(epoch.scans)} scans, states of {sorted(epoch.states)}"
            note_incomplete(self, k, epoch.opened, what)
        ordered = sorted(epoch.scans.values(), key=lambda s: self.sensor_order[s.sensor_id])
        used = where_their_platforms_are(
            self, k, ordered, epoch.states, lambda s: s.sensor_pv, lambda i: self.sensors[i][0]
        )
        tracks = self.core.step(k, k * self.scenario.dt, used)
        self.last_epoch = k
        self.counters.count("updates")
        self.counters.count("detections", tracks.detections)
        if not used:
            self.counters.count("epochs_without_scans")
        self.publish_tracks(tracks)

    # --- outputs -------------------------------------------------------------------------

    def publish_tracks(self, tracks: TrackSet) -> None:
        msg = track_array_msg(tracks, self.frame_id)
        self.tracks_pub.publish(msg)
        hdr = msg.header
        markers, now = [], set()
        for t in tracks.confirmed:
            xy = np.asarray(t.mean)[[0, 2]]
            P_xy = np.asarray(t.cov)[np.ix_([0, 2], [0, 2])]
            points = covariance_ellipse(xy, P_xy, 2.0)
            ellipse = marker(hdr, "tracks", t.track_id, Marker.LINE_STRIP, CONFIRMED_RGBA, points)
            ellipse.scale.x = 5.0  # line width, m
            label = marker(hdr, "track_ids", t.track_id, Marker.TEXT_VIEW_FACING, CONFIRMED_RGBA)
            label.pose.position.x, label.pose.position.y = float(xy[0]), float(xy[1])
            label.scale.z = 50.0  # text height, m
            label.text = str(t.track_id)
            markers += [ellipse, label]
            now.add(t.track_id)
        for gone in sorted(self.drawn - now):  # deleted or no longer confirmed
            for ns in ("tracks", "track_ids"):
                m = marker(hdr, ns, gone, Marker.LINE_STRIP, CONFIRMED_RGBA)
                m.action = Marker.DELETE
                markers.append(m)
        self.drawn = now
        self.marker_pub.publish(MarkerArray(markers=markers))
        message = (
            f"epoch {tracks.epoch} {tracks.filter_kind}: {len(tracks.confirmed)} confirmed of "
            f"{len(tracks.tracks)} tracks, {tracks.detections} detections"
        )
        self.diag_pub.publish(
            self.diagnostics_array(hdr, "activetrack/tracker_node", self.scenario.name, message)
        )


def main(args=None):
    spin_node(MultiTrackerNode, args)


if __name__ == "__main__":
    main()
