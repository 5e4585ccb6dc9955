"""PNG plots of multi-target runs (matplotlib on the Agg canvas, as :mod:`activetrack.plots`:
no pyplot state is touched).

- :func:`plot_run`: one run in the plane: the targets' true paths, the confirmed tracks' paths
  labelled with their ids, the clutter of the range-bearing scans and the platforms' paths;
- :func:`plot_gospa`: mean GOSPA vs time of several strategies, each with the band of +-1.96
  standard errors of the mean over its runs.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes

from activetrack.multitarget.data import MultiRunRecord
from activetrack.multitarget.evaluation import RunEvaluation
from activetrack.plots import new_figure
from activetrack.scenarios.schema import Scenario

__all__ = ["clutter_points", "plot_gospa", "plot_run", "track_paths"]

_CLUTTER = "0.8"  # light grey


def clutter_points(scenario: Scenario, record: MultiRunRecord) -> np.ndarray:
    """``(m, 2)`` x, y of every clutter detection (label "") of the range-bearing scans:
    z = (range, bearing) from the scan's sensor position (bearing sensors give no range).
    A record without labels (a graph run's: they stay in the sim) gives every detection."""
    kinds = {s.id: s.kind for p in scenario.platforms for s in p.sensors}
    points = [np.empty((0, 2))]
    truths = record.scan_truth or [[] for _ in record.scans]
    for scans, epoch_truths in zip(record.scans, truths, strict=True):
        labels = {(t.sensor_id, t.epoch): t.labels for t in epoch_truths}
        for scan in scans:
            if kinds.get(scan.sensor_id) != "range_bearing" or len(scan.Z) == 0:
                continue
            known = labels.get((scan.sensor_id, scan.epoch))
            clutter = np.ones(len(scan.Z), bool) if known is None else np.array(known) == ""
            r, b = scan.Z[clutter, 0], scan.Z[clutter, 1]
            xy = np.column_stack([np.cos(b), np.sin(b)]) * r[:, None]
            points.append(xy + np.asarray(scan.sensor_pv)[[0, 2]])
    return np.concatenate(points)


def track_paths(record: MultiRunRecord) -> dict[int, np.ndarray]:
    """Each confirmed track's positions ``(K+1, 2)`` (x, y) by id, NaN at the epochs it was
    not confirmed (so a line breaks there)."""
    paths: dict[int, np.ndarray] = {}
    for k, track_set in enumerate(record.tracks):
        for t in track_set.confirmed:
            if t.track_id not in paths:
                paths[t.track_id] = np.full((len(record.tracks), 2), math.nan)
            paths[t.track_id][k] = np.asarray(t.mean)[[0, 2]]
    return paths


def _draw_run(ax: Axes, scenario: Scenario, record: MultiRunRecord) -> None:
    clutter = clutter_points(scenario, record)
    if len(clutter):
        shown = "clutter" if record.scan_truth else "detections (unlabelled)"
        ax.plot(clutter[:, 0], clutter[:, 1], ".", color=_CLUTTER, ms=2, label=shown)
    truth = np.asarray(record.truth, dtype=float)
    for n, tid in enumerate(record.target_ids):
        ax.plot(truth[:, n, 0], truth[:, n, 2], "k-", lw=1.5, label="truth" if n == 0 else None)
        first = np.flatnonzero(~np.isnan(truth[:, n, 0]))
        if first.size:
            x, y = truth[first[0], n, [0, 2]]
            ax.plot(x, y, "ko", ms=4)
            ax.text(x, y, tid, fontsize="small")
    for i, (track_id, xy) in enumerate(sorted(track_paths(record).items())):
        label = "confirmed tracks" if i == 0 else None
        ax.plot(xy[:, 0], xy[:, 1], "--", color=f"C{i % 10}", lw=1.2, label=label)
        x, y = xy[np.flatnonzero(~np.isnan(xy[:, 0]))[-1]]
        ax.text(x, y, f"{track_id}", color=f"C{i % 10}", fontsize="small")
    paths = np.asarray(record.platform_paths, dtype=float)
    for j, pid in enumerate(record.platform_ids):
        label = "platforms" if j == 0 else None
        ax.plot(paths[:, j, 0], paths[:, j, 2], "b.-", ms=3, lw=0.8, label=label)
        ax.text(paths[-1, j, 0], paths[-1, j, 2], pid, color="b", fontsize="small")


def plot_run(scenario: Scenario, record: MultiRunRecord, path: str | Path) -> Path:
    """Write one run's plane view (module docstring) as a PNG at ``path``; returns it."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig = new_figure(figsize=(7, 7))
    ax = fig.subplots()
    _draw_run(ax, scenario, record)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{scenario.name}: truth, confirmed tracks (ids), platforms")
    ax.legend(loc="best", fontsize="small")
    fig.savefig(path, dpi=110, bbox_inches="tight")
    return path


def plot_gospa(evaluations: dict[str, list[RunEvaluation]], path: str | Path) -> Path:
    """Write mean GOSPA vs time of each named strategy, +-1.96 standard errors over its runs
    (no band for a single run), as a PNG at ``path``; returns it. Every run of a strategy must
    share the time grid."""
    if not evaluations or any(len(runs) == 0 for runs in evaluations.values()):
        raise ValueError("evaluations must map each strategy name to at least one run")
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig = new_figure(figsize=(8, 4.5))
    ax = fig.subplots()
    for i, (name, runs) in enumerate(evaluations.items()):
        if len({r.gospa.shape for r in runs}) != 1:
            raise ValueError(f"evaluations[{name!r}]: every run must have the same epochs")
        G = np.stack([r.gospa for r in runs])  # (runs, K)
        mean = G.mean(axis=0)
        ax.plot(runs[0].time, mean, color=f"C{i % 10}", label=f"{name} ({len(runs)} runs)")
        if len(runs) > 1:
            half = 1.96 * G.std(axis=0, ddof=1) / math.sqrt(len(runs))
            ax.fill_between(runs[0].time, mean - half, mean + half, color=f"C{i % 10}", alpha=0.2)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("GOSPA (m)")
    ax.legend(loc="best", fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    return path
