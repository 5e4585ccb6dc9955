"""What every ``activetrack reproduce NAME`` prints and writes after its report."""

from __future__ import annotations

import json
from pathlib import Path

__all__ = ["write_outputs"]


def write_outputs(plots: list[Path], data: dict, out: Path, json_path: Path | None) -> None:
    """Print the plots written, write ``data`` as ``OUT/results.json`` and, if asked, as
    ``json_path`` too."""
    print("\nplots: " + ", ".join(str(p) for p in plots))
    text = json.dumps(data, indent=2)
    out.mkdir(parents=True, exist_ok=True)
    (out / "results.json").write_text(text)
    if json_path is not None:
        json_path.parent.mkdir(parents=True, exist_ok=True)
        json_path.write_text(text)
