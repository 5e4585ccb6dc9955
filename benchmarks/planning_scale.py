"""Decision time of the multi-target planner (``MultiTargetPlanner``) against the number of
platforms, at a fixed number of confirmed tracks.

The scene is multi-target (b) (``scenarios/mt_radars_beams.yaml``) scaled up: ``--targets``
targets on a jittered grid over a square region, P controllable platforms on a ring around it,
each with one radar with a steerable 0.1 rad beam, the kinds of (b) in turn (bearing only,
coarse and fine range-bearing, clutter in every beam), and (b)'s planner (MRE positioning on the
sum of the tracks' tr(P), sector search, MRE beam assignment, the gate's q). Every target is a
confirmed track at its prior. One decision is one ``plan`` call of a fresh planner (the first
decision of a run: beams on the nearest tracks), after a warm-up that compiles the kernels;
the median over ``--repeats`` is printed per P (wall time, its range, and the process's CPU
time, steadier on a loaded machine), with the cost evaluations, the slope of
log(time) against log(P), and the epoch's budget dt (1 s, as in (b)). ``--profile P`` prints
the cProfile of one decision with P platforms; ``--record PATH`` writes every decision (the
commands, beams and predicted costs, as exact floats), ``--compare PATH`` checks that they are
the same to the last bit. The last line is ``planner_decision_ms_100t_8p=<x>`` (with the
default ``--targets 100``, the median decision with 8 platforms).

    .venv/bin/python benchmarks/planning_scale.py [--targets N] [--platforms 1,2,4,8]
        [--repeats N] [--profile P] [--record PATH | --compare PATH]
"""

from __future__ import annotations

import argparse
import cProfile
import json
import math
import os
import platform
import pstats
import statistics
import sys
import time
from pathlib import Path

import numpy as np

from activetrack.closed_loop.components import build_across_targets
from activetrack.data import Decision, PlatformSnapshot, TrackEstimate, TrackSet, heading_speed
from activetrack.scenarios import parse_scenario
from activetrack.scenarios.schema import Scenario

DT = 1.0  # s, the epoch: the decision's budget (as mt_radars_beams)
SPACING = 2000.0  # m between targets on the grid
SEED = 20100622
# The kinds of multi-target (b)'s three radars, given to the platforms in turn.
RADARS = (
    {"kind": "bearing", "sigma": 0.0015716233645501712, "pd": 0.9, "clutter_density": 10.0},
    {
        "kind": "range_bearing",
        "sigma_r": 31.622776601683793,
        "sigma_b": 0.0015716233645501712,
        "pd": 0.8,
        "r_max": 20000.0,
        "clutter_density": 0.0002,
    },
    {
        "kind": "range_bearing",
        "sigma_r": 7.745966692414834,
        "sigma_b": 0.01571623364550171,
        "pd": 0.85,
        "r_max": 20000.0,
        "clutter_density": 0.0002,
    },
)
LIMITS = {"a_max": 10.0, "psi_rate_max": math.pi / 20, "v_min": 50.0, "v_max": 200.0}


def scale_scene(
    n_targets: int, n_platforms: int, seed: int = SEED, planner: dict | None = None
) -> Scenario:
    """(b) scaled: ``n_targets`` on a jittered grid ``SPACING`` apart, ``n_platforms`` on a
    ring 5 km outside the region flying tangentially, one beam radar each (module
    docstring); ``planner`` overrides entries of (b)'s planner section."""
    data = scale_scene_data(n_targets, n_platforms, seed, planner)
    return parse_scenario(data, data["name"])


def scale_scene_data(
    n_targets: int, n_platforms: int, seed: int = SEED, planner: dict | None = None
) -> dict:
    """The scenario file's contents of :func:`scale_scene`."""
    rng = np.random.default_rng(seed)
    side = math.ceil(math.sqrt(n_targets))
    half = 0.5 * side * SPACING
    targets = []
    for i in range(n_targets):
        gx, gy = (i % side + 0.5) * SPACING - half, (i // side + 0.5) * SPACING - half
        x, y = rng.uniform(-0.3, 0.3, 2) * SPACING + (gx, gy)
        heading, speed = rng.uniform(-math.pi, math.pi), rng.uniform(50.0, 150.0)
        mean = [x, speed * math.cos(heading), y, speed * math.sin(heading)]
        targets.append(
            {
                "id": f"t{i + 1}",
                "motion": {"model": "ncv_discrete", "sigma_x": 5.0, "sigma_y": 5.0},
                "prior": {"mean": mean, "var": [100.0, 10.0, 100.0, 10.0]},
            }
        )
    platforms = []
    for j in range(n_platforms):
        a = 2 * math.pi * j / n_platforms
        r, v = half + 5000.0, 100.0
        state = [r * math.cos(a), -v * math.sin(a), r * math.sin(a), v * math.cos(a)]
        radar = {**RADARS[j % len(RADARS)], "id": f"s{j + 1}", "r_min": 100.0, "beam_width": 0.1}
        platforms.append(
            {
                "id": f"p{j + 1}",
                "initial_state": state,
                "controllable": True,
                "limits": LIMITS,
                "sensors": [radar],
            }
        )
    data = {
        "name": f"planning_scale_{n_targets}t_{n_platforms}p",
        "seed": seed,
        "dt": DT,
        "steps": 10,
        "targets": targets,
        "platforms": platforms,
        "tracker": {
            "filter": "ekf",
            "tracks": {"gate_sigmas": 3.5, "confirm_m": 4, "confirm_n": 5},
        },
        "planner": {
            "cost": "mre",
            "criterion": "trace",
            "search": "sector",
            "sector_levels": 3,
            "targets": {
                "aggregate": "weighted_sum",
                "assignment": "mre",
                "clutter_gate": "innovation",
            },
        },
        "evaluation": {"cutoff": 500.0, "order": 2, "alpha": 2},
    }
    data["planner"].update(planner or {})
    return data


def confirmed_tracks(scenario: Scenario) -> TrackSet:
    """Every target a confirmed track at its prior (mean and covariance)."""
    tracks = []
    for i, t in enumerate(scenario.targets):
        m, P = np.array(t.prior.mean), t.prior.covariance()
        tracks.append(TrackEstimate(i, "confirmed", m, P, m, P, hits=5, age=5))
    return TrackSet(0, 0.0, "ekf", tracks=tuple(tracks))


def snapshots(scenario: Scenario) -> list[PlatformSnapshot]:
    out = []
    for p in scenario.platforms:
        pv = np.array(p.initial_state)
        out.append(PlatformSnapshot(p.id, 0, 0.0, pv, *heading_speed(pv)))
    return out


def decide(scenario: Scenario, tracks: TrackSet, snaps: list[PlatformSnapshot]) -> Decision:
    """One decision of a fresh planner (its generator seeded from the scene)."""
    planner = build_across_targets(scenario, np.random.default_rng(scenario.seed))
    return planner.plan(0, tracks, snaps)


def decision_record(d: Decision) -> dict:
    """The decision's commands, beams and predicted costs as exact floats (hex)."""
    report = d.report
    return {
        "commands": [
            [c.platform_id, c.heading_change.hex(), c.speed_change.hex()] for c in d.commands
        ],
        "beams": [[b.sensor_id, b.bearing.hex(), b.track_id] for b in d.beams],
        "costs": [float(c).hex() for c in (report.predicted_costs if report else ())],
    }


def time_decisions(n_targets: int, n_platforms: int, repeats: int) -> dict:
    """Median and spread of ``repeats`` decisions (after one warm-up) and the decision."""
    scenario = scale_scene(n_targets, n_platforms)
    tracks, snaps = confirmed_tracks(scenario), snapshots(scenario)
    first = decide(scenario, tracks, snaps)  # warm-up: kernels compiled or loaded
    times, cpu = [], []
    for _ in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        d = decide(scenario, tracks, snaps)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
        if decision_record(d) != decision_record(first):
            raise RuntimeError("two decisions of the same planner inputs differ")
    return {
        "median_ms": 1e3 * statistics.median(times),
        "min_ms": 1e3 * min(times),
        "max_ms": 1e3 * max(times),
        "cpu_ms": 1e3 * statistics.median(cpu),
        "evaluations": first.report.evaluations if first.report else 0,
        "record": decision_record(first),
    }


def profile(n_targets: int, n_platforms: int, top: int = 30) -> None:
    scenario = scale_scene(n_targets, n_platforms)
    tracks, snaps = confirmed_tracks(scenario), snapshots(scenario)
    decide(scenario, tracks, snaps)
    prof = cProfile.Profile()
    prof.enable()
    decide(scenario, tracks, snaps)
    prof.disable()
    stats = pstats.Stats(prof, stream=sys.stdout)
    stats.sort_stats("cumulative").print_stats(top)
    stats.sort_stats("tottime").print_stats(top)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--targets", type=int, default=100)
    ap.add_argument("--platforms", default="1,2,4,8")
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--profile", type=int, default=None, metavar="P")
    group = ap.add_mutually_exclusive_group()
    group.add_argument("--record", type=Path, default=None)
    group.add_argument("--compare", type=Path, default=None)
    args = ap.parse_args(argv)
    if args.profile is not None:
        profile(args.targets, args.profile)
        return 0
    counts = [int(p) for p in args.platforms.split(",")]
    print(
        f"# planning_scale  python {platform.python_version()}  numpy {np.__version__}  "
        f"load {os.getloadavg()[0]:.2f}  targets {args.targets}  dt {DT:g} s  "
        f"repeats {args.repeats}"
    )
    print(
        f"{'P':>3} {'median ms':>10} {'min ms':>8} {'max ms':>8} {'CPU ms':>8} {'evaluations':>12}"
    )
    results = {}
    for P in counts:
        r = time_decisions(args.targets, P, args.repeats)
        results[P] = r
        print(
            f"{P:3d} {r['median_ms']:10.1f} {r['min_ms']:8.1f} {r['max_ms']:8.1f} "
            f"{r['cpu_ms']:8.1f} {r['evaluations']:12d}"
        )
    if len(counts) > 1:
        logs = np.log([[P, results[P]["median_ms"]] for P in counts])
        slope = np.polyfit(logs[:, 0], logs[:, 1], 1)[0]
        print(f"time ~ P^{slope:.2f} over P = {args.platforms}")
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    records = {str(P): results[P]["record"] for P in counts}
    if args.record is not None:
        args.record.write_text(json.dumps(records, indent=1))
    if args.compare is not None:
        want = json.loads(args.compare.read_text())
        differ = [P for P in records if P in want and records[P] != want[P]]
        verdict = f"differ at P = {differ}" if differ else "identical"
        print(f"decisions against {args.compare}: {verdict}")
        if differ:
            return 1
    if args.targets == 100 and 8 in results:
        print(f"planner_decision_ms_100t_8p={results[8]['median_ms']:.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
