"""The tracker's output as files (docs/track-your-data.md).

CSV: one row per track and epoch, ``epoch, time, track, status, origin, existence`` and the pv
mean ``x, vx, y, vy`` with the upper triangle of its covariance in that order (``P_x_x,
P_x_vx, ..., P_vy_vy``), then ``withheld`` (1: a confirmed track left out of the tracker's
estimate, ``tracker.tracks.report: gospa``; else 0). JSON: the track sets themselves (every field of
:class:`~activetrack.data.TrackSet` and :class:`~activetrack.data.TrackEstimate` but the
planner's samples; NaN as null), which :func:`read_tracks_json` reads back bit for bit.
"""

from __future__ import annotations

import csv
import itertools
import json
import math
from collections.abc import Iterable, Sequence
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np

from activetrack.data import TrackEstimate, TrackSet
from activetrack.tracking.detections import DataFileError

__all__ = [
    "COVARIANCE_COLUMNS",
    "TRACK_COLUMNS",
    "read_tracks_json",
    "track_sets_json",
    "write_tracks_csv",
    "write_tracks_json",
]

_PV = ("x", "vx", "y", "vy")
_UPPER = tuple(itertools.combinations_with_replacement(range(4), 2))  # (i, j), i <= j
COVARIANCE_COLUMNS = tuple(f"P_{_PV[i]}_{_PV[j]}" for i, j in _UPPER)
TRACK_COLUMNS = (
    "epoch", "time", "track", "status", "origin", "existence", *_PV, *COVARIANCE_COLUMNS,
    "withheld",
)  # fmt: skip
_ARRAYS = ("mean", "cov", "state", "state_cov")
_FLOATS = ("priority", "existence", "nis", "ess")


def write_tracks_csv(path: str | Path, track_sets: Iterable[TrackSet]) -> None:
    """One row per track and epoch (module docstring), floats exact."""
    with Path(path).open("w", newline="") as f:
        out = csv.writer(f)
        out.writerow(TRACK_COLUMNS)
        for ts in track_sets:
            for t in ts.tracks:
                mean = np.asarray(t.mean, dtype=float)
                P = np.asarray(t.cov, dtype=float).reshape(4, 4)
                values = [*mean, *(P[i, j] for i, j in _UPPER)]
                out.writerow(
                    [ts.epoch, repr(float(ts.time)), t.track_id, t.status, t.origin]
                    + [repr(float(v)) for v in (t.existence, *values)]
                    + [int(t.withheld)]
                )


def _plain(value: Any) -> Any:
    """JSON-ready: arrays as (nested) lists, NaN and infinities as null."""
    if isinstance(value, np.ndarray):
        return _plain(value.tolist())
    if isinstance(value, list | tuple):
        return [_plain(v) for v in value]
    if isinstance(value, float | np.floating):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, np.integer):
        return int(value)
    return value


def _json_fields(obj: Any, skip: str) -> dict:
    """A dataclass's fields but ``skip``, JSON-ready."""
    return {f.name: _plain(getattr(obj, f.name)) for f in fields(obj) if f.name != skip}


def track_sets_json(track_sets: Iterable[TrackSet]) -> list[dict]:
    """The track sets as JSON-ready dicts (without samples)."""
    return [
        {**_json_fields(ts, "tracks"), "tracks": [_json_fields(t, "samples") for t in ts.tracks]}
        for ts in track_sets
    ]


def write_tracks_json(path: str | Path, track_sets: Iterable[TrackSet], **extra: Any) -> None:
    """``{"track_sets": [...], **extra}`` (``extra``: JSON-ready values, e.g. GOSPA)."""
    doc = {**{k: _plain(v) for k, v in extra.items()}, "track_sets": track_sets_json(track_sets)}
    Path(path).write_text(json.dumps(doc, indent=1, allow_nan=False) + "\n")


def _estimate(d: dict) -> TrackEstimate:
    values = dict(d)
    for name in _ARRAYS:
        values[name] = np.array(values[name], dtype=float)
    for name in _FLOATS:
        values[name] = math.nan if values.get(name) is None else float(values[name])
    return TrackEstimate(**values)


def read_tracks_json(path: str | Path) -> list[TrackSet]:
    """The track sets of a file written by :func:`write_tracks_json`."""
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
        entries: Sequence[dict] = doc["track_sets"]
    except OSError as exc:
        raise DataFileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except (ValueError, KeyError, TypeError) as exc:
        raise DataFileError(f'{path}: not a tracks file {{"track_sets": [...]}}: {exc}') from None
    out = []
    for i, entry in enumerate(entries):
        try:
            values = dict(entry)
            values["tracks"] = tuple(_estimate(t) for t in values["tracks"])
            values["state_names"] = tuple(values["state_names"])
            out.append(TrackSet(**values))
        except (ValueError, KeyError, TypeError) as exc:
            raise DataFileError(f"{path}: track_sets[{i}]: {exc}") from None
    return out
