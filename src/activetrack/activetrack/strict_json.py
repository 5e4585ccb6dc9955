"""Strict JSON for what the command line writes (``summary.json``, every ``--json`` file, the
reproductions' ``results.json``):
NaN and infinities (an absent target's error, a bound a nonlinear model has not) as null, so
that any JSON reader takes the file and ``run`` and ``batch`` write the same values alike."""

from __future__ import annotations

import json
import math
from pathlib import Path


def json_safe(value):
    """``value`` with every non-finite float (in dicts, lists and tuples) replaced by None."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    return value


def write_json(path: str | Path, data: dict) -> None:
    """``data`` to ``path`` as strict, indented JSON (folders created)."""
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    Path(path).write_text(json.dumps(json_safe(data), indent=2, allow_nan=False))
