"""Strict JSON for every file the command line writes: non-finite floats become null, so any
JSON reader (``allow_nan=False`` ones included) takes the file."""

from __future__ import annotations

import json
import math
import sys
import types

import numpy as np

from activetrack.strict_json import json_safe, write_json
from activetrack_experiments.reproduction import Reproduction, RunsOption


def strict_load(text: str):
    def refuse(name):
        raise ValueError(f"non-standard JSON constant {name}")

    return json.loads(text, parse_constant=refuse)


def test_non_finite_floats_become_null_at_any_depth(tmp_path):
    data = {"a": math.nan, "b": [1.5, -math.inf, (np.float64(math.inf), 2)], "c": {"d": math.nan}}
    assert json_safe(data) == {"a": None, "b": [1.5, None, [None, 2]], "c": {"d": None}}
    path = tmp_path / "deep" / "x.json"  # folders are created
    write_json(path, data)
    assert strict_load(path.read_text()) == {
        "a": None,
        "b": [1.5, None, [None, 2]],
        "c": {"d": None},
    }


def test_a_reproductions_json_files_are_strict(tmp_path, monkeypatch, capsys):
    """A paper whose document holds NaN (a standard error of one run) writes null to both
    ``--json`` and ``results.json``."""
    paper = types.ModuleType("activetrack_experiments.strictpaper")
    paper.reproduce = lambda runs, **kw: {"runs": runs, "stderr": math.nan}
    paper.format_report = lambda res: "report"
    paper.save_figures = lambda res, out: []
    monkeypatch.setitem(sys.modules, "activetrack_experiments.strictpaper", paper)
    repro = Reproduction(
        "strictpaper", "A paper with a NaN.", RunsOption(1, 1, "runs"), document=lambda r, f, w: r
    )
    out = tmp_path / "out"
    assert repro.main(["--jobs", "1", "--json", str(tmp_path / "r.json"), "--out", str(out)]) == 0
    assert capsys.readouterr().out.startswith("report")
    for path in (tmp_path / "r.json", out / "results.json"):
        assert strict_load(path.read_text()) == {"runs": 1, "stderr": None}
