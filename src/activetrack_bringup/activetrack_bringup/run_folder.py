"""Where a run writes its files: ``runs/<scenario name>-<timestamp>`` unless ``--out`` says.

The scenario schema already restricts names to safe identifiers; this sanitises again so
that no name (a scenario built in code, an older file) can put the folder outside ``root``.
"""

from __future__ import annotations

import re
from datetime import datetime
from pathlib import Path

__all__ = ["run_dir_for", "safe_name"]

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
