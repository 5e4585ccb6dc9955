"""argparse ``type=`` functions of the ``activetrack`` command line's numbers: a bad one is a
one-line usage error, exit code 2 (helpers and limits: :mod:`activetrack.argtypes`,
:mod:`activetrack.limits`).
"""

from __future__ import annotations

from activetrack.argtypes import float_in_range, int_in_range
from activetrack.limits import MAX_JOBS, MAX_RATE, MAX_RUNS, MAX_SEED, MAX_WALL_SECONDS

__all__ = ["duration", "jobs", "rate", "run_index", "runs", "sim_rate", "timeout"]

runs = int_in_range(1, MAX_RUNS)  # --runs: Monte Carlo runs
jobs = int_in_range(1, MAX_JOBS)  # --jobs: worker processes
run_index = int_in_range(0, MAX_SEED)  # --run: Monte Carlo run index (seeding)
timeout = float_in_range(0.0, MAX_WALL_SECONDS, lo_inclusive=False)  # --timeout: wall seconds
duration = float_in_range(0.0, MAX_WALL_SECONDS, lo_inclusive=False)  # --duration: seconds
rate = float_in_range(0.0, MAX_RATE, lo_inclusive=False)  # --rate: playback speed factor
# run --rate: the sim's free-mode rate, in its parameter's range (sim_node.PARAMS; the launch
# file test checks that they agree)
SIM_RATE_RANGE = (1e-3, 1e6)
sim_rate = float_in_range(*SIM_RATE_RANGE)
