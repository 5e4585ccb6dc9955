"""The most bytes one of the graph's messages of each type can take, from the scenario.

A reader drops a message longer than that before any other work (with a key: as foreign,
before the hash; without: ``rejected.too_large``, before deserialisation): a 100,000-detection
scan from outside costs a length check. The bounds are generous (every string at its longest,
every sequence at the most the scenario and ``activetrack.limits`` allow, a factor of 2 on
top): a message of the graph stays far below its bound (a clean run with one counted foreign
would fail the tests that check none is).
"""

from __future__ import annotations

from activetrack import limits
from activetrack.closed_loop.components import scene_sensors, scene_targets

DOUBLE = 8
SLACK = 2  # the factor above the sum of the parts
# Header, strings and fixed fields of any of the types: ids are at most MAX_ID_LENGTH, and
# the free-form strings (frame ids, kinds, names) are taken at 1 KiB each.
FIXED = 16 * 1024
ID = 4 + limits.MAX_ID_LENGTH + 4  # a CDR string: length, characters, NUL and padding
# /diagnostics carries other drivers' arrays too: their size is theirs; the graph's own hold
# a node's counters (a few dozen, and per-epoch notes of timeouts).
DIAGNOSTICS_BYTES = 16 * 1024 * 1024


def most_tracks(scenario) -> int:
    """Tracks one TrackArray may hold: the tracker's ``max_tracks`` started from detections
    and one per target started from its prior."""
    return scenario.tracker.tracks.max_tracks + len(scene_targets(scenario))


def max_bytes(scenario) -> dict[str, int]:
    """Message type name -> the most bytes one message of it may take in this scenario's graph."""
    sensors = scene_sensors(scenario)
    dim = max((int(s.dim_z) for _, s in sensors.values()), default=1)
    n_sensors = max(len(sensors), 1)
    n_targets = max(len(scene_targets(scenario)), 1)
    tracks = most_tracks(scenario)
    n = limits.MAX_STATE_DIM
    per_track = (
        FIXED + ID + DOUBLE * (2 * (n + n * n) + 4 + 16 + scenario.tracker.planner_samples * n)
    )
    sizes = {
        "Scan": FIXED + DOUBLE * (limits.MAX_SCAN_DETECTIONS * dim + dim * dim),
        "PlatformState": FIXED + ID * limits.MAX_SENSORS,
        "TrackArray": FIXED + tracks * per_track,
        "ManoeuvreCommand": FIXED,
        "BeamCommand": FIXED,
        "SensorSelection": FIXED + ID * n_sensors,
        # a cost per track and a few more (planning across targets names each track's)
        "PlanReport": FIXED + (tracks + 64) * (ID + DOUBLE),
        "GroundTruthArray": FIXED + n_targets * (ID + 1024 + DOUBLE * (6 + n + 1)),
        "RunMetrics": FIXED + n_targets * (ID + 22 * DOUBLE) + ID * n_sensors,
    }
    sizes = {name: SLACK * b for name, b in sizes.items()}
    sizes["DiagnosticArray"] = DIAGNOSTICS_BYTES
    return sizes
