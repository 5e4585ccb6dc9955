"""What the ROS node graph adds over the batch loop, on the same scenario, in one process.

Runs the closed loop twice per repetition, alternating: `activetrack batch` (core only) and
`activetrack run` (sim, tracker and planner nodes in one process, bag recording on), checks they
give the same track, and prints both wall times and the ratio. Default scenario: Hernandez
2-sensor two-step planning with the 10,000-particle PF.

    .venv/bin/python benchmarks/graph_overhead.py [SCENARIO] [--repeats N]
"""

from __future__ import annotations

import argparse
import statistics
import tempfile
import time

import numpy as np

from activetrack.closed_loop.batch import run_batch
from activetrack.scenarios import load_scenario
from activetrack_bringup.runner import run_graph


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("scenario", nargs="?", default="scenarios/hernandez_2sensor_two.yaml")
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    scenario = load_scenario(args.scenario)
    batch_t, graph_t, batch_plan, graph_plan = [], [], [], []
    for i in range(args.repeats):
        order = ("batch", "graph") if i % 2 == 0 else ("graph", "batch")
        for which in order:
            start = time.perf_counter()
            if which == "batch":
                b = run_batch(scenario, runs=1)
                batch_t.append(time.perf_counter() - start)
                batch_plan.append(b.records[0].planning_time_s)
            else:
                with tempfile.TemporaryDirectory() as tmp:
                    g = run_graph(args.scenario, run_dir=tmp, plots=False)
                graph_t.append(time.perf_counter() - start)
                graph_plan.append(g.summary.records[0].planning_time_s)
        tracks = zip(b.records[0].track_series(), g.summary.records[0].track_series(), strict=True)
        same = all(np.array_equal(x, y) for x, y in tracks)
        print(
            f"repeat {i}: batch {batch_t[-1]:.2f} s, graph {graph_t[-1]:.2f} s, same track: {same}"
        )
        if not same:
            print("error: the graph's track differs from the batch run")
            return 1
    mb, mg = statistics.median(batch_t), statistics.median(graph_t)
    # Ratio pair by pair (each graph run against the batch run next to it): robust to the
    # machine's speed drifting during the benchmark.
    ratio = statistics.median(g / b for g, b in zip(graph_t, batch_t, strict=True))
    print(
        f"scenario {scenario.name}: {scenario.steps} epochs, {scenario.tracker.particles} particles"
    )
    print(f"median wall time: batch {mb:.2f} s, ROS graph in one process {mg:.2f} s")
    # Both loops make the same planner calls; on a noisy machine their time swings by seconds.
    # Without it, what remains is what the graph adds (messages, executor, bag, evaluator).
    pairs = zip(graph_t, graph_plan, batch_t, batch_plan, strict=True)
    added = statistics.median((g - gp) - (b - bp) for g, gp, b, bp in pairs)
    print(f"graph_overhead={100 * (ratio - 1):.1f}% (median of paired ratios; target <= 25%)")
    print(
        f"graph_added_s={added:.2f} (wall time outside the planner, graph minus batch), "
        f"{100 * added / mb:.1f}% of the batch run"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
