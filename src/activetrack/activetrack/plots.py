"""PNG plots of closed-loop runs (matplotlib figures drawn with the Agg canvas: no pyplot, so
the caller's backend and pyplot state are left alone)."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

if TYPE_CHECKING:
    from collections.abc import Callable, Iterable

    from activetrack.closed_loop.batch import BatchSummary


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


def plot_run(summary: BatchSummary, out_dir: str | Path) -> list[Path]:
    """Trajectories of one run, and RMSE vs the PCRLB over time. Returns the files written."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    rec = summary.records[0]
    files = []

    fig = new_figure(figsize=(6, 6))
    ax = fig.subplots()
    ax.plot(rec.truth[:, 0], rec.truth[:, 2], "k-", label="target (truth)")
    ax.plot(rec.estimate[:, 0], rec.estimate[:, 2], "r--", label="estimate")
    for j, pid in enumerate(rec.platform_ids):
        path = rec.platform_paths[:, j]
        ax.plot(path[:, 0], path[:, 2], ".-", label=f"platform {pid}")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(loc="best", fontsize="small")
    ax.set_title(summary.scenario)
    files.append(out / "trajectories.png")
    fig.savefig(files[-1], dpi=110, bbox_inches="tight")

    k = np.arange(1, summary.steps + 1)
    fig = new_figure(figsize=(10, 4))
    axes = fig.subplots(1, 2, sharey=True)
    for ax, coord, rmse, bound in (
        (axes[0], "x", summary.rmse_x_t, summary.bound_x_t),
        (axes[1], "y", summary.rmse_y_t, summary.bound_y_t),
    ):
        ax.plot(k, rmse, "r-", label=f"RMSE ({summary.runs} run(s))")
        ax.plot(k, bound, "k--", label="PCRLB along the flown paths")
        ax.set_xlabel("epoch k")
        ax.set_title(f"{coord}-coordinate")
        ax.set_yscale("log")
        ax.legend(fontsize="small")
    axes[0].set_ylabel("m")
    files.append(out / "rmse_vs_bound.png")
    fig.savefig(files[-1], dpi=110, bbox_inches="tight")
    return files
