"""argparse ``type=`` functions of the ``activetrack`` command line's numbers.

A bad number is a one-line usage error (``error: argument --runs: must be an integer in
[1, 100000], got '0'``, exit code 2) before anything runs. The helpers and limits are the
core's (:mod:`activetrack.argtypes`, :mod:`activetrack.limits`), shared with the experiments.
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
