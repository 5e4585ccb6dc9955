"""argparse ``type=`` functions of the ``activetrack`` command line's numbers and output
paths: a bad one is a one-line usage error, exit code 2, before anything runs (helpers and
limits: :mod:`activetrack.argtypes`, :mod:`activetrack.limits`).
"""

from __future__ import annotations

import argparse
import os
import tempfile
from pathlib import Path

from activetrack.argtypes import float_in_range, int_in_range
from activetrack.limits import MAX_JOBS, MAX_RATE, MAX_RUNS, MAX_SEED, MAX_WALL_SECONDS, MIN_RATE

__all__ = [
    "duration",
    "jobs",
    "output_file",
    "output_folder",
    "rate",
    "run_index",
    "runs",
    "sim_rate",
    "timeout",
]

runs = int_in_range(1, MAX_RUNS)  # --runs: Monte Carlo runs
jobs = int_in_range(1, MAX_JOBS)  # --jobs: worker processes
run_index = int_in_range(0, MAX_SEED)  # --run: Monte Carlo run index (seeding)
timeout = float_in_range(0.0, MAX_WALL_SECONDS, lo_inclusive=False)  # --timeout: wall seconds
duration = float_in_range(0.0, MAX_WALL_SECONDS, lo_inclusive=False)  # --duration: seconds
# --rate: playback speed factor (below MIN_RATE a bag's second takes over a quarter hour)
rate = float_in_range(MIN_RATE, MAX_RATE)
# run --rate: the sim's free-mode rate, in its parameter's range (sim_node.PARAMS; the launch
# file test checks that they agree)
SIM_RATE_RANGE = (1e-3, 1e6)
sim_rate = float_in_range(*SIM_RATE_RANGE)


def _exists(path: Path) -> bool:
    try:
        return path.exists()
    except OSError:  # e.g. no permission to look: taken as absent, the probe below says why
        return False


def _takes_new_entries(folder: Path) -> str | None:
    """Why no file can be created in the existing path ``folder`` (None: one can). Tried, not
    guessed from permission bits: root, read-only mounts and /proc answer only to a try."""
    if not folder.is_dir():
        return f"{folder} is not a folder"
    try:
        fd, probe = tempfile.mkstemp(dir=folder, prefix=".activetrack-probe-")
    except OSError as exc:
        return f"cannot create files in {folder}: {exc.strerror or exc}"
    os.close(fd)
    os.unlink(probe)
    return None


def output_file(text: str) -> str:
    """--json PATH: a file this process can write: its folder exists and takes new files, and
    the path is not a folder (or a file that cannot be overwritten)."""
    path = Path(text)
    if not text or (_exists(path) and path.is_dir()):
        raise argparse.ArgumentTypeError(f"{text!r} is a folder, not a file")
    folder = path.parent
    if not _exists(folder):
        raise argparse.ArgumentTypeError(f"the folder of {text} ({folder}) does not exist")
    why = _takes_new_entries(folder)
    if why is None and _exists(path) and not os.access(path, os.W_OK):
        why = f"{text} exists and cannot be overwritten"
    if why is not None:
        raise argparse.ArgumentTypeError(why)
    return text


def output_folder(text: str) -> str:
    """--out DIR (and record's BAG): a folder that exists or can be created: the nearest
    existing path above it is a folder that takes new entries."""
    path = Path(text)
    if not text:
        raise argparse.ArgumentTypeError("an empty path is no folder")
    nearest = path
    while not _exists(nearest) and nearest != nearest.parent:
        nearest = nearest.parent
    why = _takes_new_entries(nearest)
    if why is not None:
        raise argparse.ArgumentTypeError(f"{text} cannot be a folder: {why}")
    return text
