"""Particle filter step time and peak memory from 1e3 to 1e6 particles, compiled vs numpy.

Run as ``.venv/bin/python benchmarks/pf_scale.py [--quick]`` (issue 15, part 6).

The filter of ``benchmarks/filters.py`` (bearings-only NCV target, one turning sensor, SIR with
systematic resampling at every step) runs for N = 1e3, 1e4, 1e5 and 1e6 particles on both paths
of ``activetrack.kernels``: ``compiled`` (numba) and ``numpy`` (the reference; the same
particles bit for bit, which the table checks). Each (N, path) runs in a fresh child process,
so that its peak memory is its own:

- step time: median over the steps of ``ParticleFilter.step`` (predict + update), after one
  warm-up run of a few steps (imports, kernel loading), as wall time and as the process's CPU
  time. On a loaded machine a step longer than a scheduler time slice (a few ms: 1e5 particles
  and up) is preempted, and its wall time grows with the load; the CPU time does not, so the
  compiled vs numpy ratio is taken from it;
- peak memory: the child's peak resident set size (``ru_maxrss``) minus its resident size just
  before the filter was made, i.e. what the particles, weights and the step's temporaries add
  (numba's arrays bypass Python's allocator, so ``tracemalloc`` would miss them).

The last line is ``pf_scale_compiled_vs_numpy_1e6=<ratio>``.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

SIZES = (1_000, 10_000, 100_000, 1_000_000)
PATHS = ("compiled", "numpy")


def _rss_kib() -> int:
    """Current resident set size in KiB (Linux /proc)."""
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") // 1024


def child(n: int, path: str, steps: int) -> dict:
    """Time ``steps`` PF steps of ``n`` particles on ``path``; step times and peak memory."""
    sys.path.insert(0, str(Path(__file__).parent))
    import filters as fb  # the scenario of benchmarks/filters.py

    from activetrack import kernels
    from activetrack.allocator import tune_allocator
    from activetrack.filters import Measurement, ParticleFilter
    from activetrack.models import BearingSensor, NearlyConstantVelocity

    tune_allocator()
    kernels.set_kernels(path)
    sc = fb.Scenario(n_steps=steps)
    run = fb.simulate(sc, 1000)
    model, sensor = NearlyConstantVelocity(sc.q), BearingSensor(sc.sigma)
    meas = [
        [Measurement(sensor, run.sensor[k + 1], [run.z[k]], run.times[k])]
        for k in range(sc.n_steps)
    ]

    def make(count: int) -> ParticleFilter:
        X0 = fb.initial_particles(sc, count, run.seed)
        return ParticleFilter(model, particles=X0, rng=np.random.default_rng([run.seed, 2]))

    warm = make(1000)  # warm-up: imports, kernels, numpy code paths
    for k in range(3):
        warm.step(run.times[k], meas[k])
    del warm
    before = _rss_kib()
    f = make(n)
    times, cpu = [], []
    for k in range(sc.n_steps):
        t0, c0 = time.perf_counter(), time.process_time()
        f.step(run.times[k], meas[k])
        cpu.append(time.process_time() - c0)
        times.append(time.perf_counter() - t0)
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss  # KiB on Linux
    return {
        "n": n,
        "path": path,
        "median_s": statistics.median(times),
        "cpu_median_s": statistics.median(cpu),
        "peak_mib": max(peak - before, 0) / 1024.0,
        "particles_sha": hashlib.sha256(f.particles.tobytes()).hexdigest(),
    }


def run_child(n: int, path: str, steps: int) -> dict:
    out = subprocess.run(
        [sys.executable, __file__, "--child", str(n), path, "--steps", str(steps)],
        check=True,
        capture_output=True,
        text=True,
    )
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--quick", action="store_true", help="1e3 to 1e5 particles, few steps")
    p.add_argument("--steps", type=int, default=None, help="steps per size (default 30; 10 at 1e6)")
    p.add_argument("--child", nargs=2, metavar=("N", "PATH"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.child:
        print(json.dumps(child(int(args.child[0]), args.child[1], args.steps or 30)))
        return 0

    sizes = SIZES[:3] if args.quick else SIZES
    print(f"# PF scale benchmark  python {platform.python_version()}  numpy {np.__version__}")
    print(f"# load average at start: {os.getloadavg()[0]:.1f} (2-core machine shared: noisy)")
    header = ("particles", "path", "wall step", "CPU step", "CPU/particle", "peak mem")
    print("{:>10} {:>9} {:>13} {:>13} {:>13} {:>10}".format(*header))
    results = {}
    for n in sizes:
        steps = args.steps or (5 if args.quick else (10 if n >= 1_000_000 else 30))
        for path in PATHS:
            r = run_child(n, path, steps)
            results[n, path] = r
            print(
                f"{n:>10,} {path:>9} {r['median_s'] * 1e3:10.3f} ms "
                f"{r['cpu_median_s'] * 1e3:10.3f} ms {r['cpu_median_s'] / n * 1e9:10.1f} ns "
                f"{r['peak_mib']:6.1f} MiB"
            )
        same = results[n, "compiled"]["particles_sha"] == results[n, "numpy"]["particles_sha"]
        ratio = results[n, "numpy"]["cpu_median_s"] / results[n, "compiled"]["cpu_median_s"]
        print(f"{'':>10} compiled vs numpy (CPU): {ratio:.2f}x; same final particles: {same}")
    n_top = sizes[-1]
    ratio = results[n_top, "numpy"]["cpu_median_s"] / results[n_top, "compiled"]["cpu_median_s"]
    label = f"{n_top:.0e}".replace("+0", "")
    print(f"pf_scale_compiled_vs_numpy_{label}={ratio:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
