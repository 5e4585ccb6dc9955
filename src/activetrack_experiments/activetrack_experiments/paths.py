"""Where the papers' scenario files are: an explicit directory, or the package's own copies."""

from __future__ import annotations

from importlib import resources
from pathlib import Path

__all__ = ["find_scenarios_dir", "scenario_path"]


def _packaged() -> Path:
    return Path(str(resources.files("activetrack_experiments") / "scenario_files"))


def find_scenarios_dir(explicit: str | Path | None = None, pattern: str = "*.yaml") -> Path:
    """``explicit`` if given (it must hold files matching ``pattern``), else the scenario files
    installed with this package (package data; in a source checkout, the repository's
    ``scenarios/``)."""
    directory = Path(explicit) if explicit is not None else _packaged()
    if not directory.is_dir() or not any(directory.glob(pattern)):
        where = "scenarios" if explicit is not None else "the installed package data"
        raise FileNotFoundError(
            f"{where}: no {pattern} files in {directory}; pass an existing directory"
        )
    return directory


def scenario_path(name: str, scenarios_dir: str | Path | None = None) -> Path:
    """The file of scenario ``name`` (``"hernandez_1sensor_single"``, with or without
    ``.yaml``) in :func:`find_scenarios_dir`."""
    stem = name[:-5] if name.endswith(".yaml") else name
    return find_scenarios_dir(scenarios_dir, f"{stem}.yaml") / f"{stem}.yaml"
