"""Memory of a long free run of the ROS graph in one process: does anything grow per epoch?

Runs the default scenario's geometry for 2,000 epochs in free mode (sim time runs on at
``--rate`` whatever the planner does), bag recording on, samples the process's resident set
size every 100 epochs and prints the least-squares slope after the warm-up (KiB per epoch),
with the bag's growth per epoch over the same span (linear growth: a constant per epoch).
The evaluator keeps the run's record (each epoch's tracks without the planner's samples, its
scans and decision: a few kB), not messages, and the path markers republish only their newest
chunk; what grows is the writers' transient-local history, sized to the run so that a late
joiner gets all of it (about the size of one epoch's messages per epoch: the PF track with its
planner samples dominates).

    .venv/bin/python benchmarks/memory_soak.py [--epochs 2000] [--rate 250]
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

import numpy as np
import yaml

from activetrack_bringup.runner import run_graph

PAGE = os.sysconf("SC_PAGE_SIZE")


def rss_kib() -> float:
    with open("/proc/self/statm") as f:
        return int(f.read().split()[1]) * PAGE / 1024


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--epochs", type=int, default=2000)
    parser.add_argument("--rate", type=float, default=250.0, help="sim seconds per wall second")
    parser.add_argument("--warmup", type=int, default=500, help="epochs before the slope fit")
    parser.add_argument("--particles", type=int, default=1000)
    parser.add_argument("--no-bag", action="store_true", help="without the recorder")
    args = parser.parse_args()
    data = yaml.safe_load(Path("scenarios/default.yaml").read_text())
    data.update(name="memory_soak", steps=args.epochs)
    data["tracker"]["particles"] = args.particles
    samples: list[tuple[int, float, int]] = []
    with tempfile.TemporaryDirectory() as tmp:
        scenario = Path(tmp) / "memory_soak.yaml"
        scenario.write_text(yaml.safe_dump(data))
        run_dir = Path(tmp) / "run"

        def sample(graph):
            evaluator = next(n for n in graph.nodes if n.get_name() == "activetrack_evaluator")
            k = len(evaluator.tracks) - 1
            if k >= 0 and k % 100 == 0 and (not samples or samples[-1][0] != k):
                bag = run_dir / "bag" / "bag.mcap"
                samples.append((k, rss_kib(), bag.stat().st_size if bag.exists() else 0))
                print(f"epoch {k:5d}  RSS {samples[-1][1] / 1024:8.1f} MiB  bag "
                      f"{samples[-1][2] / 2**20:7.1f} MiB", flush=True)  # fmt: skip

        result = run_graph(
            scenario,
            mode="free",
            run_dir=run_dir,
            plots=False,
            record=not args.no_bag,
            timeout=24 * 3600,
            sim_params={"rate": args.rate},
            during_spin=sample,
        )
    k = np.array([s[0] for s in samples], dtype=float)
    rss = np.array([s[1] for s in samples])
    bag = np.array([s[2] for s in samples], dtype=float)
    fit = k >= args.warmup
    slope = np.polyfit(k[fit], rss[fit], 1)[0]
    bag_slope = np.polyfit(k[fit], bag[fit], 1)[0] / 1024
    late = k >= (args.warmup + k.max()) / 2  # bag growth per epoch: early vs late half
    bag_early = np.polyfit(k[fit & ~late], bag[fit & ~late], 1)[0] / 1024
    bag_late = np.polyfit(k[late], bag[late], 1)[0] / 1024
    print(f"\n{args.epochs} epochs, free mode at {args.rate:g}x, wall {result.wall_time_s:.1f} s")
    print(f"RSS slope after epoch {args.warmup}: {slope:.2f} KiB/epoch")
    print(f"bag growth: {bag_slope:.1f} KiB/epoch (first half {bag_early:.1f}, "
          f"second half {bag_late:.1f}: linear if equal)")  # fmt: skip
    print(f"rss_slope_kib_per_epoch={slope:.3f} bag_kib_per_epoch={bag_slope:.2f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
