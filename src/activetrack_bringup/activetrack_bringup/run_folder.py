"""Where a run writes its files: ``runs/<scenario name>-<timestamp>`` unless ``--out`` says.

The scenario schema already restricts names to safe identifiers; this sanitises again so
that no name (a scenario built in code, an older file) can put the folder outside ``root``.
"""

from __future__ import annotations

import json
import os
import re
from datetime import datetime
from pathlib import Path

from activetrack_bringup.interrupts import SIGNAL_NAMES

__all__ = ["interrupted_before_start", "run_dir_for", "safe_name", "write_summary"]

MAX_NAME_LENGTH = 100
_UNSAFE = re.compile(r"[^A-Za-z0-9_.-]+")


def safe_name(name: str) -> str:
    """``name`` with only [A-Za-z0-9_.-] kept (runs of others become '_'), no leading '.',
    at most MAX_NAME_LENGTH characters, never empty ('scenario')."""
    cleaned = _UNSAFE.sub("_", str(name)).lstrip(".")[:MAX_NAME_LENGTH]
    return cleaned or "scenario"


def run_dir_for(
    scenario_name: str, out: str | Path | None = None, root: Path = Path("runs")
) -> Path:
    """The run folder: ``out`` as given (the user's choice), else
    ``root/<safe name>-<YYYYmmdd-HHMMSS-microseconds>``, always inside ``root``."""
    if out:  # None or "": the default folder below (as run_graph treats run_dir)
        return Path(out)
    stamp = datetime.now().strftime("%Y%m%d-%H%M%S-%f")
    folder = Path(root) / f"{safe_name(scenario_name)}-{stamp}"
    # safe_name leaves no separator and no leading '.', so this holds; kept as a guard.
    if Path(root).resolve() not in folder.resolve().parents:
        raise ValueError(f"run folder {folder} would lie outside {root}")
    return folder


def interrupted_before_start(run_dir: Path, exit_code: int, wall: float) -> dict:
    """The summary.json of a run stopped by a signal (exit code 130 or 143) before its graph
    ran an epoch, written to ``run_dir`` (created) and returned: no metrics, the keys of every
    run's summary (activetrack_bringup.runner.GraphRun.to_json)."""
    signal_name = SIGNAL_NAMES[exit_code]
    data = {
        "complete": False,
        "status": "interrupted",
        "detail": f"{signal_name} before the graph started",
        "epochs_completed": 0,
        "wall_time_s": wall,
        "real_time_factor": 0.0,
        "bag": None,
        "run_dir": str(run_dir),
        "diagnostics": {},
        "foreign_messages_dropped": {},
        "restarts": {},
        "timeouts": {},
        "ros": None,
    }
    write_summary(run_dir, data)
    return data


def write_summary(run_dir: Path, data: dict) -> Path:
    """``run_dir``/summary.json, written whole (a temporary file renamed over it)."""
    run_dir = Path(run_dir)
    run_dir.mkdir(parents=True, exist_ok=True)
    path = run_dir / "summary.json"
    part = run_dir / ".summary.json.part"
    part.write_text(json.dumps(data, indent=2))
    os.replace(part, path)
    return path
