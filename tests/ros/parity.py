"""Two runs of a scenario compared bit for bit: a graph run's record (rebuilt by the runner's
evaluator from the graph's messages) against the batch loop's, or two graph runs."""

from __future__ import annotations

import numpy as np

from activetrack.closed_loop.record import RunRecord
from activetrack.data import TrackSet

_TRACK_FIELDS = (
    "track_id", "status", "origin", "hits", "misses", "missed_detections", "existence", "withheld"
)  # fmt: skip


def same_tracks(a: TrackSet, b: TrackSet) -> bool:
    """The same tracks: ids, status, bookkeeping, existence and the report, filter states and
    pv kinematics."""
    return (a.epoch, a.filter_kind, a.detections, a.unassociated) == (
        b.epoch,
        b.filter_kind,
        b.detections,
        b.unassociated,
    ) and all(
        [getattr(x, f) for f in _TRACK_FIELDS] == [getattr(y, f) for f in _TRACK_FIELDS]
        and np.array_equal(x.state, y.state)
        and np.array_equal(x.state_cov, y.state_cov)
        and np.array_equal(x.mean, y.mean)
        and np.array_equal(x.cov, y.cov)
        for x, y in zip(a.tracks, b.tracks, strict=True)
    )


def _decided(record: RunRecord) -> list:
    """Per decision: commands (platform, heading and speed change, gating), beams, the
    selection and the plan report's predicted costs."""
    return [
        (
            d.epoch,
            [(c.platform_id, c.heading_change, c.speed_change, c.take_measurement)
             for c in d.commands],
            list(d.beams),
            d.selected_sensor_ids,
            None if d.report is None else tuple(d.report.predicted_costs),
        )
        for d in record.decisions
    ]  # fmt: skip


def assert_same_run(a: RunRecord, b: RunRecord) -> None:
    """Bit for bit: truth, platform paths, which sensors looked and detected and which targets
    they covered, every scan's detections, every track array and every decision."""
    assert (a.target_ids, a.sensor_ids, a.platform_ids) == (
        b.target_ids,
        b.sensor_ids,
        b.platform_ids,
    )
    assert np.array_equal(a.truth, b.truth, equal_nan=True), "truth"
    assert np.array_equal(a.platform_paths, b.platform_paths), "platform_paths"
    for name in ("looked", "detected", "observed"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert len(a.scans) == len(b.scans)
    for k, (x, y) in enumerate(zip(a.scans, b.scans, strict=True), start=1):
        assert [s.sensor_id for s in x] == [s.sensor_id for s in y], k
        assert all(np.array_equal(s.Z, t.Z) for s, t in zip(x, y, strict=True)), k
        assert all(np.array_equal(s.sensor_pv, t.sensor_pv) for s, t in zip(x, y, strict=True))
        assert [s.fov for s in x] == [s.fov for s in y], k
    assert len(a.tracks) == len(b.tracks)
    for k, (x, y) in enumerate(zip(a.tracks, b.tracks, strict=True)):
        assert same_tracks(x, y), f"tracks of epoch {k}"
    assert _decided(a) == _decided(b)
