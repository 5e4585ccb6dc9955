"""Time (or profile) the full tracker step on the spread scenes of ``scale_scene.py``.

Run with ``.venv/bin/python benchmarks/step_profile.py [--targets 3 30 100 300 1000]
[--steps 10] [--clutter 20] [--profile [--sort tottime] [--top 25]]``: per scene (``--clutter``
false alarms per scan and radar) the median and p90 of ``Tracker.step`` over the epochs after
the first (CPU time, ``time.process_time``), the live tracks at the end and the tracker's
counters; ``--profile`` prints cProfile's top functions.
"""

from __future__ import annotations

import argparse
import cProfile
import os
import pstats
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import scale_scene


def step_times(
    n: int, steps: int, seed: int = 0, clutter: float = scale_scene.CLUTTER_PER_SCAN
) -> tuple[np.ndarray, object]:
    """CPU seconds of each step of a fresh tracker on the scene of ``n`` targets."""
    scene = scale_scene.build(n, seed, steps, clutter)
    tracker = scene.tracker()
    out = []
    for k, row in enumerate(scene.scans, start=1):
        t0 = time.process_time()
        tracker.step(k, k * scale_scene.DT, row)
        out.append(time.process_time() - t0)
    return np.array(out), tracker


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--targets", type=int, nargs="+", default=[3, 30, 100, 300, 1000])
    p.add_argument("--steps", type=int, default=10)
    p.add_argument("--clutter", type=float, default=scale_scene.CLUTTER_PER_SCAN)
    p.add_argument("--profile", action="store_true")
    p.add_argument("--sort", default="cumulative", help="cProfile order (cumulative, tottime)")
    p.add_argument("--top", type=int, default=25, help="functions printed")
    args = p.parse_args(argv)
    print(f"# load average {os.getloadavg()[0]:.1f}")
    for n in args.targets:
        if args.profile:
            prof = cProfile.Profile()
            prof.enable()
        dt, tracker = step_times(n, args.steps, clutter=args.clutter)
        if args.profile:
            prof.disable()
        ms = 1e3 * dt[1:]
        print(
            f"n={n} median_ms={np.median(ms):.1f} p90_ms={np.percentile(ms, 90):.1f} "
            f"live={len(tracker.book.tracks)} counters={dict(tracker.counters)}"
        )
        if args.profile:
            pstats.Stats(prof).sort_stats(args.sort).print_stats(args.top)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
