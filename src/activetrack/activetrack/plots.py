"""PNG plots of closed-loop runs (Agg canvas, no pyplot: the caller's backend is left alone):
a run in the plane, each target's RMSE against its PCRLB, mean GOSPA per strategy."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable, Mapping

    from activetrack.closed_loop.batch import BatchSummary
    from activetrack.closed_loop.evaluation import RunEvaluation
    from activetrack.closed_loop.record import RunRecord
    from activetrack.models.base import SensorModel


def new_figure(**kwargs: Any) -> Figure:
    """A matplotlib Figure on its own Agg canvas (``Figure(**kwargs)``), outside pyplot."""
    fig = Figure(**kwargs)
    FigureCanvasAgg(fig)
    return fig


def write_figures(
    figures: Iterable[tuple[str, Callable[[], Figure | None]]],
    out: str | Path,
    *,
    dpi: int = 110,
    tight_layout: bool = True,
    bbox_inches: str | None = None,
) -> list[Path]:
    """Draw each ``(file name, draw)`` of ``figures`` and write it as a PNG into ``out``; a
    ``draw`` returning None writes nothing. Returns the files written, in order."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    files = []
    for name, draw in figures:
        fig = draw()
        if fig is None:
            continue
        if tight_layout:
            fig.tight_layout()
        files.append(out / name)
        fig.savefig(files[-1], dpi=dpi, bbox_inches=bbox_inches)
    return files


def _saved(fig: Figure, path: str | Path, **options: Any) -> Path:
    """``fig`` written as a PNG at ``path`` (110 dpi, its folder made); the file."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110, **options)
    return path


def plot_errors(summary: BatchSummary, path: str | Path) -> Path:
    """Write each target's RMSE against its PCRLB over time, x and y, as a PNG at ``path``
    (the summary's ``rmse_x_t`` / ``bound_x_t``; closed_loop.batch says what they average);
    returns the file."""
    k = np.arange(1, summary.steps + 1)
    fig = new_figure(figsize=(10, 4))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, coord, rmse, bound in (
        (axes[0], "x", summary.rmse_x_t, summary.bound_x_t),
        (axes[1], "y", summary.rmse_y_t, summary.bound_y_t),
    ):
        for n, target in enumerate(summary.target_ids):
            tag = f" {target}" if len(summary.target_ids) > 1 else ""
            ax.plot(k, rmse[n], "-", color=f"C{n % 10}", label=f"RMSE{tag} ({summary.runs} run(s))")
            ax.plot(k, bound[n], "--", color=f"C{n % 10}", label=f"PCRLB{tag}")
        ax.set_xlabel("epoch k")
        ax.set_title(f"{coord}-coordinate")
        ax.set_yscale("log")
        ax.legend(fontsize="small")
    axes[0].set_ylabel("m")
    return _saved(fig, path, bbox_inches="tight")


_CLUTTER = "0.8"  # light grey


def clutter_points(sensors: Mapping[str, SensorModel], record: RunRecord) -> np.ndarray:
    """``(m, 2)`` x, y of every clutter detection (label "") of the scans whose sensor fixes a
    position from one detection (its ``inverse_position``; bearings fix none), ``sensors`` by
    id. A record without labels (a graph run's: they stay in the sim) gives every detection."""
    points: list[np.ndarray] = [np.empty((0, 2))]
    truths = record.scan_truth or [[] for _ in record.scans]
    for scans, epoch_truths in zip(record.scans, truths, strict=True):
        labels = {(t.sensor_id, t.epoch): t.labels for t in epoch_truths}
        for scan in scans:
            sensor = sensors.get(scan.sensor_id)
            if sensor is None or len(scan.Z) == 0:
                continue
            known = labels.get((scan.sensor_id, scan.epoch))
            clutter = np.ones(len(scan.Z), bool) if known is None else np.array(known) == ""
            s = np.asarray(scan.sensor_pv, dtype=float)
            for z in np.asarray(scan.Z)[clutter]:
                fix = sensor.inverse_position(z, s)
                if fix is None:
                    break
                points.append(fix[0][None])
    return np.concatenate(points)


def track_paths(record: RunRecord) -> dict[int, np.ndarray]:
    """Each confirmed track's positions ``(K+1, 2)`` (x, y) by id, NaN at the epochs it was
    not confirmed (so a line breaks there)."""
    paths: dict[int, np.ndarray] = {}
    for k, track_set in enumerate(record.tracks):
        for t in track_set.confirmed:
            if t.track_id not in paths:
                paths[t.track_id] = np.full((len(record.tracks), 2), math.nan)
            paths[t.track_id][k] = np.asarray(t.mean)[[0, 2]]
    return paths


def _draw_run(ax: Axes, sensors: Mapping[str, SensorModel], record: RunRecord) -> None:
    clutter = clutter_points(sensors, record)
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


def plot_run(
    name: str, sensors: Mapping[str, SensorModel], record: RunRecord, path: str | Path
) -> Path:
    """Write one run's plane view as a PNG at ``path`` (the targets' true paths, the
    confirmed tracks' paths with their ids, the clutter that fixes a position, the platforms'
    paths); ``sensors``: the scene's by id; returns the file."""
    fig = new_figure(figsize=(7, 7))
    ax = fig.subplots()
    _draw_run(ax, sensors, record)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(f"{name}: truth, confirmed tracks (ids), platforms")
    ax.legend(loc="best", fontsize="small")
    return _saved(fig, path, bbox_inches="tight")


def plot_gospa(evaluations: dict[str, list[RunEvaluation]], path: str | Path) -> Path:
    """Write mean GOSPA vs time of each named strategy, +-1.96 standard errors over its runs
    (no band for a single run), as a PNG at ``path``; returns it. Every run of a strategy must
    share the time grid."""
    if not evaluations or any(len(runs) == 0 for runs in evaluations.values()):
        raise ValueError("evaluations must map each strategy name to at least one run")
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
    return _saved(fig, path)
