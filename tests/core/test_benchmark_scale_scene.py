"""benchmarks/scale_scene.py: the spread scenes the tracker step is timed on (issue 28)."""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np

_PATH = Path(__file__).resolve().parents[2] / "benchmarks" / "scale_scene.py"
_spec = importlib.util.spec_from_file_location("bench_scale_scene", _PATH)
assert _spec is not None and _spec.loader is not None
scale = importlib.util.module_from_spec(_spec)
sys.modules[_spec.name] = scale  # dataclasses look their module up while the class is built
_spec.loader.exec_module(scale)


def test_radars_per_scene_size():
    # round(sqrt(n / 8))^2 radars: 1, 4, 16, 36 and 121 for 3, 30, 100, 300 and 1,000 targets
    for n, radars in [(3, 1), (30, 4), (100, 16), (300, 36), (1000, 121)]:
        scene = scale.build(n, seed=1, steps=1)
        assert len(scene.sensors) == radars and len(scene.scans[0]) == radars
        assert len(scene.priors) == n and scene.truth.shape == (2, n, 4)
        side = scene.cells * scale.CELL
        assert (scene.truth[0][:, [0, 2]] >= 0).all() and (scene.truth[0][:, [0, 2]] <= side).all()


def test_a_scene_is_seeded_and_its_tracker_holds_the_targets():
    a, b = scale.build(30, seed=2, steps=3), scale.build(30, seed=2, steps=3)
    for row_a, row_b in zip(a.scans, b.scans, strict=True):
        for sa, sb in zip(row_a, row_b, strict=True):
            assert np.array_equal(sa.Z, sb.Z)
    # about CLUTTER_PER_SCAN false alarms plus Pd x the targets in view per scan
    m = np.mean([s.Z.shape[0] for row in a.scans for s in row])
    assert scale.CLUTTER_PER_SCAN < m < scale.CLUTTER_PER_SCAN + 30
    tracker = a.tracker()
    for k, row in enumerate(a.scans, start=1):
        ts = tracker.step(k, k * scale.DT, row)
    assert len(ts.confirmed) >= 28  # the priors' tracks, nearly all held
    assert tracker.not_started == 0  # max_tracks leaves room for every clutter track
