"""Decision times of the PCRLB planner on the Hernandez scenarios, and the throughput of the
vectorised PCRLB against one candidate per call (the baseline, same process, same data).

Plans open loop from the prior, as the paper does (sec. 3.2), for the first ``--epochs``
decisions of each case (quadrant search, 1,000 Monte Carlo samples), and prints per case the
median and maximum decision time, cost evaluations per decision and evaluations per second.

    .venv/bin/python benchmarks/planning.py [--epochs N] [--cases 1s,2s,3s,1t,2t,3t]
"""

from __future__ import annotations

import argparse
import statistics
import time
from pathlib import Path

import numpy as np

from activetrack.allocator import tune_allocator
from activetrack.bounds.pcrlb import covariance_bound, measurement_information, pcrlb_step
from activetrack.models.sensors import BearingSensor
from activetrack.scenarios import load_scenario
from activetrack_experiments.hernandez import plan_case

SCENARIOS = Path(__file__).parents[1] / "scenarios"
CASES = {
    "1s": "hernandez_1sensor_single",
    "2s": "hernandez_2sensor_single",
    "3s": "hernandez_3sensor_single",
    "1t": "hernandez_1sensor_two",
    "2t": "hernandez_2sensor_two",
    "3t": "hernandez_3sensor_two",
}
TARGET_S = 0.3  # two-step, 3-sensor decision, median


def decision_times(name: str, epochs: int) -> dict:
    scenario = load_scenario(SCENARIOS / f"{name}.yaml")
    scenario = scenario.model_copy(update={"steps": min(epochs, scenario.steps)})
    case = plan_case(scenario)
    t = np.array(case.decision_times)
    evals = float(np.mean(case.evaluations))
    return {
        "median_s": float(np.median(t)),
        "max_s": float(t.max()),
        "evaluations": evals,
        "evaluations_per_s": float(np.sum(case.evaluations) / t.sum()),
    }


def pcrlb_throughput(n_candidates: int, M: int = 1000, reps: int = 20) -> tuple[float, float]:
    """Seconds per evaluation: (batched call over all candidates, one call per candidate)."""
    rng = np.random.default_rng(0)
    X = rng.normal([0.0, 8.0, 0.0, 6.0], [20.0, 1.0, 20.0, 1.0], size=(M, 4))
    heading = np.linspace(-np.pi / 10, np.pi / 10, n_candidates)
    S = np.stack(
        [
            1800 - 200 * np.cos(heading),
            -40 + 0 * heading,
            2000 - 200 * np.sin(heading),
            -40 + 0 * heading,
        ],
        axis=-1,
    )
    sensor = BearingSensor(sigma=0.01, r_min=100.0)
    F = np.eye(4)
    F[0, 1] = F[2, 3] = 5.0
    Q = 1e-6 * np.eye(4)
    J0 = np.diag([1 / 400, 1.0, 1 / 400, 1.0])

    def batched():
        J = pcrlb_step(J0, F, Q, measurement_information(sensor, S, X))
        return covariance_bound(J)

    def one_by_one():
        return [
            covariance_bound(pcrlb_step(J0, F, Q, measurement_information(sensor, s, X))) for s in S
        ]

    np.testing.assert_allclose(np.array(one_by_one()), batched(), rtol=1e-9)
    out = []
    for fn in (batched, one_by_one):
        times = []
        for _ in range(reps):
            t0 = time.perf_counter()
            fn()
            times.append(time.perf_counter() - t0)
        out.append(statistics.median(times) / n_candidates)
    return out[0], out[1]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--epochs", type=int, default=10, help="decisions per case (first N)")
    ap.add_argument("--cases", default=",".join(CASES), help="comma list of " + ",".join(CASES))
    args = ap.parse_args()
    print("vectorised PCRLB (eq. 3 + eq. 8-9, bearing sensor, 1,000 samples), per evaluation:")
    for c in (9, 45, 1000):
        b, one = pcrlb_throughput(c)
        print(
            f"  {c:5d} candidates per call: {b * 1e6:8.1f} us ({1 / b:9.0f} evaluations/s); "
            f"one per call {one * 1e6:8.1f} us; ratio {one / b:5.1f}x"
        )
    print(f"decision times, quadrant search, open loop, first {args.epochs} decisions:")
    print(f"  {'case':<26} {'median':>9} {'max':>9} {'evals/decision':>15} {'evals/s':>9}")
    results = {}
    for key in args.cases.split(","):
        name = CASES[key]
        r = results[key] = decision_times(name, args.epochs)
        print(
            f"  {name:<26} {r['median_s'] * 1e3:7.1f}ms {r['max_s'] * 1e3:7.1f}ms "
            f"{r['evaluations']:15.0f} {r['evaluations_per_s']:9.0f}"
        )
    if "3t" in results:
        m = results["3t"]["median_s"]
        verdict = "met" if m < TARGET_S else "not met"
        print(f"two_step_3sensor_decision_median_s={m:.3f} (target < {TARGET_S}: {verdict})")
    return 0


if __name__ == "__main__":
    # As the command line and the nodes do: the timings are those users get.
    tune_allocator()
    raise SystemExit(main())
