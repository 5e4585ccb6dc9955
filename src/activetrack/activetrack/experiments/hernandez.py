"""Reproduce Hernandez (Fusion 2004) Tables 1-2 and Figs. 2-3 (``activetrack reproduce hernandez``).

For 1, 2 and 3 sensors and single-step (eq. 11) / two-step (eq. 13-15) planning on the sec. 5.1
scenario: plan the sensor paths open loop from the prior (sec. 3.2), average the PCRLB RMSE
bounds sqrt(J_k^-1(1,1)), sqrt(J_k^-1(3,3)) over k = 1..30, then track the target along the
planned paths with a 10,000-particle SIR filter (sec. 5.2) over seeded Monte Carlo runs and
average the filter RMSEs the same way. Also compares the quadrant search with the 101 x 101
grid on the 1-sensor single-step case (sec. 4.2, Fig. 2). See docs/hernandez.md.

    python -m activetrack.experiments.hernandez [--runs N] [--json PATH] [--out DIR] ...
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from activetrack.argtypes import int_in_range
from activetrack.bounds.pcrlb import (
    covariance_bound,
    gaussian_samples,
    pcrlb_step,
    propagate_samples,
)
from activetrack.filters import Measurement, ParticleFilter
from activetrack.geometry import covariance_ellipse
from activetrack.limits import (
    MAX_GRID_SIZE,
    MAX_JOBS,
    MAX_PARTICLES,
    MAX_PLANNER_BATCH,
    MAX_RUNS,
    MAX_SAMPLES,
    MAX_SEARCH_EVALUATIONS,
    MAX_SEED,
)
from activetrack.planning import (
    PlannerPlatform,
    PlanSettings,
    TargetBelief,
    plan,
    platform_information,
    platforms_from_scenario,
)
from activetrack.scenarios import build_motion_model, load_scenario
from activetrack.scenarios.schema import PlannerConfig

# Hernandez Table 1: (sensors, horizon) -> (bound_x, bound_y, pf_rmse_x, pf_rmse_y), metres.
PAPER_TABLE1 = {
    (1, 1): (12.3, 13.9, 13.9, 18.1),
    (1, 2): (11.9, 10.1, 13.2, 10.7),
    (2, 1): (7.1, 7.3, 7.6, 9.1),
    (2, 2): (6.8, 6.7, 7.5, 7.1),
    (3, 1): (5.9, 6.0, 6.9, 6.8),
    (3, 2): (5.0, 5.1, 6.1, 7.0),
}
# Table 2: sensors -> (% bound x, % bound y, % pf x, % pf y) improvement of two-step.
PAPER_TABLE2 = {
    1: (3.6, 27.6, 4.5, 40.6),
    2: (5.5, 8.1, 2.0, 21.7),
    3: (15.1, 15.2, 11.1, -2.6),
}
HORIZON_NAMES = {1: "single", 2: "two"}


def find_scenarios_dir(explicit: str | None = None) -> Path:
    """The directory holding hernandez_*.yaml: --scenarios, $ACTIVETRACK_SCENARIOS, the
    repository's scenarios/ (editable install) or ./scenarios."""
    candidates = [explicit, os.environ.get("ACTIVETRACK_SCENARIOS")]
    candidates += [str(Path(__file__).resolve().parents[4] / "scenarios"), "scenarios"]
    for c in candidates:
        if c and (Path(c) / "hernandez_1sensor_single.yaml").is_file():
            return Path(c)
    raise FileNotFoundError(
        "hernandez_*.yaml scenarios not found; pass --scenarios DIR or set ACTIVETRACK_SCENARIOS"
    )


@dataclass
class PlannedCase:
    """Open-loop plan of one case: paths (K+1, P, 4), bounds (K, 2), bound covariances."""

    sensors: int
    horizon: int
    search: str
    platform_ids: list
    paths: np.ndarray
    bounds: np.ndarray
    P: np.ndarray
    target_mean: np.ndarray
    evaluations: list = field(default_factory=list)
    decision_times: list = field(default_factory=list)
    iterations: list = field(default_factory=list)


def plan_case(
    scenario,
    *,
    search: str | None = None,
    grid_size: int | None = None,
    mc_samples: int | None = None,
    seed: int | None = None,
) -> PlannedCase:
    """Plan the sensor paths open loop from the prior (Hernandez sec. 3.2) and record the PCRLB
    along them: J_{k+1} by eq. 3 with J_Z (eq. 8-9) over the prior samples at k+1."""
    model = build_motion_model(scenario.target.motion)
    dt = scenario.dt
    F, Q = model.transition_matrix(dt), model.process_noise(dt)
    overrides = {}
    if search is not None:
        overrides["search"] = search
    if grid_size is not None:
        overrides["grid_size"] = grid_size
    settings = PlanSettings.from_config(scenario.planner, **overrides)
    rng = np.random.default_rng(scenario.seed if seed is None else seed)
    M = scenario.planner.mc_samples if mc_samples is None else mc_samples
    prior = scenario.target.prior
    C0 = prior.covariance()
    X0 = gaussian_samples(np.asarray(prior.mean), C0, M, rng)
    K = scenario.steps
    samples = propagate_samples(X0, F, Q, K, rng)  # prior samples at k = 1..K (sec. 3.2)
    platforms = platforms_from_scenario(scenario)
    J = covariance_bound(C0)  # eq. 4: J_0 = C_0^{-1}
    X = X0
    paths = [np.stack([p.pv for p in platforms])]
    bounds, Ps = [], []
    case = PlannedCase(
        len(platforms),
        settings.horizon,
        settings.search.search,
        [p.platform_id for p in platforms],
        None,
        None,
        None,
        None,
    )
    for k in range(K):
        # The planner looks ahead noise-free from the prior samples at k (l = 1e-8 here).
        result = plan(platforms, TargetBelief(J, X), settings, F=F, Q=Q, dt=dt)
        case.evaluations.append(result.report.evaluations)
        case.decision_times.append(result.report.wall_time_s)
        case.iterations.append(result.report.iterations)
        nxt = []
        for p in platforms:
            m = result.manoeuvre(p.platform_id)
            nxt.append(
                PlannerPlatform(
                    p.platform_id, m.next_pv, p.sensors, p.limits, heading=m.heading, speed=m.speed
                )
            )
        platforms = nxt
        X = samples[k]
        J_Z = sum(platform_information(p.sensors, p.pv, X) for p in platforms)
        J = pcrlb_step(J, F, Q, J_Z)
        P = covariance_bound(J)
        Ps.append(P)
        bounds.append([np.sqrt(P[0, 0]), np.sqrt(P[2, 2])])
        paths.append(np.stack([p.pv for p in platforms]))
    case.paths = np.stack(paths)
    case.bounds = np.array(bounds)
    case.P = np.stack(Ps)
    mean0 = np.asarray(prior.mean, dtype=float)
    case.target_mean = np.stack([np.linalg.matrix_power(F, k) @ mean0 for k in range(K + 1)])
    return case


def _track_runs(args) -> np.ndarray:
    """Squared PF errors (runs, K, 4) for Monte Carlo runs ``run_ids`` along fixed paths."""
    scenario_path, paths, run_ids, particles, seed = args
    scenario = load_scenario(scenario_path)
    model = build_motion_model(scenario.target.motion)
    dt, K = scenario.dt, scenario.steps
    platforms = platforms_from_scenario(scenario)
    prior = scenario.target.prior
    mean0, C0 = np.asarray(prior.mean, dtype=float), prior.covariance()
    out = np.empty((len(run_ids), K, 4))
    for n, r in enumerate(run_ids):
        sim_rng, pf_rng = (
            np.random.default_rng(s) for s in np.random.SeedSequence([seed, r]).spawn(2)
        )
        truth = mean0 + np.linalg.cholesky(C0) @ sim_rng.standard_normal(4)
        pf = ParticleFilter(model, mean0, C0, n_particles=particles, rng=pf_rng)
        for k in range(1, K + 1):
            truth = model.sample(truth, dt, sim_rng)
            ms = []
            for i, p in enumerate(platforms):
                s_pv = paths[k, i]
                for sensor in p.sensors:
                    # No measurement inside the minimum detection range (sec. 2.3).
                    z = (
                        sensor.sample(truth, s_pv, sim_rng)
                        if sensor.in_range(truth, s_pv)
                        else None
                    )
                    ms.append(Measurement(sensor, s_pv, z, k * dt))
            pf.step(k * dt, ms)
            out[n, k - 1] = (pf.mean - truth) ** 2
    return out


def track_case(scenario_path, paths, runs: int, particles: int, seed: int, jobs: int) -> np.ndarray:
    """PF RMSE per epoch (K, 2) in x and y over ``runs`` seeded runs (run r: SeedSequence
    ([seed, r]) split into truth/measurement and filter generators)."""
    chunks = [
        list(c) for c in np.array_split(np.arange(runs), max(1, min(jobs * 4, runs))) if len(c)
    ]
    tasks = [(str(scenario_path), paths, c, particles, seed) for c in chunks]
    if jobs > 1 and len(tasks) > 1:
        with ProcessPoolExecutor(max_workers=jobs) as pool:
            sq = np.concatenate(list(pool.map(_track_runs, tasks)))
    else:
        sq = np.concatenate([_track_runs(t) for t in tasks])
    mse = sq.mean(axis=0)
    return np.sqrt(mse[:, [0, 2]])


def _fmt_table1(cases: dict) -> str:
    lines = [
        "Table 1: RMSE bounds averaged over k = 1..30 (PF RMSEs in brackets), metres",
        "ours / paper",
    ]
    head = f"{'':14s}" + "".join(
        f"{f'{n} sensor' + ('s' if n > 1 else ''):^42s}" for n in (1, 2, 3)
    )
    sub = f"{'Direction':14s}" + "".join(f"{'Single-Step':^21s}{'Two-Step':^21s}" for _ in range(3))
    lines += [head, sub]
    for axis, name in ((0, "x-coordinate"), (1, "y-coordinate")):
        row = f"{name:14s}"
        for n in (1, 2, 3):
            for R in (1, 2):
                c = cases.get((n, R))
                if c is None:
                    row += f"{'-':^21s}"
                    continue
                b = c["bound_x" if axis == 0 else "bound_y"]
                e = c["pf_rmse_x" if axis == 0 else "pf_rmse_y"]
                cell = f"{b:.1f} ({e:.1f})" if e is not None else f"{b:.1f}"
                row += f"{cell:^21s}"
        lines.append(row)
        row = f"{'  paper':14s}"
        for n in (1, 2, 3):
            for R in (1, 2):
                p = PAPER_TABLE1[(n, R)]
                row += f"{f'{p[axis]:.1f} ({p[2 + axis]:.1f})':^21s}"
        lines.append(row)
    return "\n".join(lines)


def improvements(cases: dict) -> dict:
    """Table 2: % improvement of two-step over single-step per sensor count."""
    out = {}
    for n in (1, 2, 3):
        s, t = cases.get((n, 1)), cases.get((n, 2))
        if s is None or t is None:
            continue
        vals = []
        for key in ("bound_x", "bound_y", "pf_rmse_x", "pf_rmse_y"):
            if s[key] is None or t[key] is None:
                vals.append(None)
            else:
                vals.append(100.0 * (s[key] - t[key]) / s[key])
        out[n] = vals
    return out


def _fmt_table2(cases: dict) -> str:
    imp = improvements(cases)
    lines = [
        "Table 2: % improvement of two-step over single-step (PF RMSEs in brackets)",
        f"{'Direction':14s}"
        + "".join(f"{f'{n} sensor' + ('s' if n > 1 else ''):^30s}" for n in (1, 2, 3)),
    ]

    def fmt(v):
        return "-" if v is None else f"{v:.1f}"

    for axis, name in ((0, "x-coordinate"), (1, "y-coordinate")):
        row, prow = f"{name:14s}", f"{'  paper':14s}"
        for n in (1, 2, 3):
            v = imp.get(n)
            row += f"{(fmt(v[axis]) + ' (' + fmt(v[2 + axis]) + ')') if v else '-':^30s}"
            p = PAPER_TABLE2[n]
            prow += f"{f'{p[axis]:.1f} ({p[2 + axis]:.1f})':^30s}"
        lines += [row, prow]
    return "\n".join(lines)


def _ellipse(ax, centre, P, scale=10.0, **kw):
    """Outline of the 1-sigma ellipse of the position block of P, magnified ``scale`` times."""
    pts = covariance_ellipse(centre, P[np.ix_([0, 2], [0, 2])], scale)
    ax.plot(pts[:, 0], pts[:, 1], **kw)


def _plot_paths(ax, case, title):
    tm = case.target_mean
    ax.plot(tm[:, 0], tm[:, 2], "k--", lw=1, label="target (prior mean)")
    for i, pid in enumerate(case.platform_ids):
        ax.plot(case.paths[:, i, 0], case.paths[:, i, 2], "-o", ms=2, label=f"sensor {pid}")
    for k in range(1, len(case.P) + 1, 3):
        _ellipse(ax, tm[k, [0, 2]], case.P[k - 1], color="tab:red", lw=0.7)
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_title(title, fontsize=9)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.legend(fontsize=7)


def save_figures(out: Path, planned: dict, rmse: dict, comparison, scenario, samples_fig) -> list:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    out.mkdir(parents=True, exist_ok=True)
    t = scenario.dt * np.arange(1, scenario.steps + 1)
    if comparison is not None and (1, 1) in planned:
        fig, axs = plt.subplots(2, 2, figsize=(11, 9))
        X = samples_fig
        for k in range(0, X.shape[0], 2):
            axs[0, 0].plot(X[k, :, 0], X[k, :, 2], ",", color="tab:blue", alpha=0.3)
        axs[0, 0].set_title("(a) prior target samples, k = 0, 2, ..., 30", fontsize=9)
        axs[0, 0].set_aspect("equal", adjustable="datalim")
        _plot_paths(axs[0, 1], planned[(1, 1)], "(b) quadrant search, 10x PCRLB ellipses")
        _plot_paths(axs[1, 0], comparison, "(c) 101x101 grid search, 10x PCRLB ellipses")
        for case, lab in ((planned[(1, 1)], "quadrant"), (comparison, "grid 101x101")):
            axs[1, 1].plot(t, case.bounds.max(axis=1), label=lab)
        axs[1, 1].set_xlabel("time (s)")
        axs[1, 1].set_ylabel("b_k (m)")
        axs[1, 1].set_title("(d) RMSE bound b_k (eq. 10)", fontsize=9)
        axs[1, 1].legend()
        fig.tight_layout()
        f = out / "fig2_1sensor_quadrant_vs_grid.png"
        fig.savefig(f, dpi=110)
        plt.close(fig)
        files.append(f)
    if (2, 1) in planned and (2, 2) in planned:
        fig, axs = plt.subplots(2, 2, figsize=(11, 9))
        _plot_paths(axs[0, 0], planned[(2, 1)], "(a) 2 sensors, single-step")
        _plot_paths(axs[0, 1], planned[(2, 2)], "(b) 2 sensors, two-step")
        for R, lab in ((1, "single-step"), (2, "two-step")):
            axs[1, 0].plot(t, planned[(2, R)].bounds[:, 1], label=lab)
            if (2, R) in rmse:
                axs[1, 1].plot(t, rmse[(2, R)][:, 1], label=lab)
        axs[1, 0].set_title("(c) y RMSE bound", fontsize=9)
        axs[1, 1].set_title("(d) y PF RMSE", fontsize=9)
        for ax in axs[1]:
            ax.set_xlabel("time (s)")
            ax.set_ylabel("m")
            ax.legend()
        fig.tight_layout()
        f = out / "fig3_2sensors_single_vs_two.png"
        fig.savefig(f, dpi=110)
        plt.close(fig)
        files.append(f)
    # All cases: bounds and PF RMSEs against time.
    fig, axs = plt.subplots(1, 2, figsize=(12, 4.5))
    for (n, R), case in sorted(planned.items()):
        lab = f"{n} sensor(s), {HORIZON_NAMES[R]}-step"
        (line,) = axs[0].plot(t, case.bounds.max(axis=1), label=lab)
        if (n, R) in rmse:
            axs[1].plot(t, rmse[(n, R)].max(axis=1), color=line.get_color(), label=lab)
    axs[0].set_title("b_k = max(x, y) RMSE bound")
    axs[1].set_title("max(x, y) PF RMSE")
    for ax in axs:
        ax.set_xlabel("time (s)")
        ax.set_ylabel("m")
        ax.set_yscale("log")
        ax.legend(fontsize=7)
    fig.tight_layout()
    f = out / "bounds_and_rmse_all_cases.png"
    fig.savefig(f, dpi=110)
    plt.close(fig)
    files.append(f)
    return files


def _parse(argv):
    ap = argparse.ArgumentParser(
        prog="activetrack reproduce hernandez",
        description="Reproduce Hernandez (2004) Tables 1-2 and Figs. 2-3.",
    )
    ap.add_argument(
        "--runs",
        type=int_in_range(0, MAX_RUNS, note="0: the bounds only"),
        default=100,
        help="Monte Carlo PF runs per case (100; 0: the bounds only)",
    )
    ap.add_argument(
        "--particles",
        type=int_in_range(1, MAX_PARTICLES),
        default=10000,
        help="PF particles (10,000)",
    )
    ap.add_argument(
        "--mc-samples",
        type=int_in_range(1, MAX_SAMPLES),
        default=None,
        help="planner Monte Carlo samples (scenario: 1000)",
    )
    ap.add_argument("--sensors", default="1,2,3", help="sensor counts, e.g. 1,2,3")
    ap.add_argument("--horizons", default="1,2", help="planning horizons, 1 and/or 2")
    ap.add_argument(
        "--search",
        default=None,
        choices=("quadrant", "grid", "sector"),
        help="override the scenarios' search (quadrant)",
    )
    ap.add_argument(
        "--grid-size",
        type=int_in_range(2, MAX_GRID_SIZE),
        default=101,
        help="grid of the comparison (101)",
    )
    ap.add_argument(
        "--no-comparison", action="store_true", help="skip the quadrant vs 101x101 grid comparison"
    )
    ap.add_argument(
        "--seed", type=int_in_range(0, MAX_SEED), default=None, help="seed (scenario seed)"
    )
    ap.add_argument(
        "--jobs",
        type=int_in_range(1, MAX_JOBS),
        default=os.cpu_count() or 1,
        help="PF worker processes",
    )
    ap.add_argument("--json", default=None, help="write the numbers to this JSON file")
    ap.add_argument("--out", default="runs/reproduce-hernandez", help="figure directory")
    ap.add_argument("--no-figures", action="store_true", help="do not write PNG figures")
    ap.add_argument("--scenarios", default=None, help="directory with hernandez_*.yaml")
    args = ap.parse_args(argv)
    try:
        args.sensor_counts = sorted({int(s) for s in args.sensors.split(",")})
        args.horizon_list = sorted({int(s) for s in args.horizons.split(",")})
    except ValueError:
        ap.error("--sensors and --horizons take comma-separated integers")
    if not set(args.sensor_counts) <= {1, 2, 3}:
        ap.error("--sensors must be among 1,2,3")
    if not set(args.horizon_list) <= {1, 2}:
        ap.error("--horizons must be among 1,2")
    # --search grid plans on the scenarios' grid (101 x 101): two steps nest two grids.
    if args.search == "grid" and 2 in args.horizon_list:
        per_decision = PlannerConfig().grid_size ** 4
        if per_decision > MAX_SEARCH_EVALUATIONS:
            ap.error(
                f"--search grid with --horizons 2 costs {per_decision:.2e} cost evaluations per "
                f"decision, at most {MAX_SEARCH_EVALUATIONS:.0e}: use --horizons 1"
            )
    # The grid comparison scores up to 2,048 grid points against every planner sample at once.
    samples = 1000 if args.mc_samples is None else args.mc_samples
    batch = min(args.grid_size**2, 2048) * samples
    if not args.no_comparison and 1 in args.sensor_counts and batch > MAX_PLANNER_BATCH:
        ap.error(
            f"--mc-samples {samples} with --grid-size {args.grid_size} scores {batch:.2e} "
            f"sample-candidate pairs at once, at most {MAX_PLANNER_BATCH:.1e} (about 1 GB)"
        )
    return args


def run(args) -> dict:
    """Run the experiment for parsed ``args``; returns the JSON document."""
    sdir = find_scenarios_dir(args.scenarios)
    planned, rmse, cases, paths_of = {}, {}, {}, {}
    scenario = None
    for n in args.sensor_counts:
        for R in args.horizon_list:
            path = sdir / f"hernandez_{n}sensor_{HORIZON_NAMES[R]}.yaml"
            scenario = load_scenario(path)
            seed = scenario.seed if args.seed is None else args.seed
            t0 = time.perf_counter()
            case = plan_case(scenario, search=args.search, mc_samples=args.mc_samples, seed=seed)
            plan_s = time.perf_counter() - t0
            planned[(n, R)] = case
            paths_of[(n, R)] = path
            entry = {
                "sensors": n,
                "horizon": R,
                "search": case.search,
                "bound_x": float(case.bounds[:, 0].mean()),
                "bound_y": float(case.bounds[:, 1].mean()),
                "pf_rmse_x": None,
                "pf_rmse_y": None,
                "evaluations_per_decision": float(np.mean(case.evaluations)),
                "decision_time_s": float(np.mean(case.decision_times)),
                "sensor_iterations_per_decision": float(np.mean(case.iterations)),
                "planning_time_s": plan_s,
                "paper_bound_x": PAPER_TABLE1[(n, R)][0],
                "paper_bound_y": PAPER_TABLE1[(n, R)][1],
                "paper_pf_rmse_x": PAPER_TABLE1[(n, R)][2],
                "paper_pf_rmse_y": PAPER_TABLE1[(n, R)][3],
                "bound_x_by_epoch": case.bounds[:, 0].tolist(),
                "bound_y_by_epoch": case.bounds[:, 1].tolist(),
                "sensor_paths": {
                    pid: case.paths[:, i].tolist() for i, pid in enumerate(case.platform_ids)
                },
            }
            if args.runs > 0:
                t0 = time.perf_counter()
                r = track_case(path, case.paths, args.runs, args.particles, seed, args.jobs)
                rmse[(n, R)] = r
                entry.update(
                    pf_rmse_x=float(r[:, 0].mean()),
                    pf_rmse_y=float(r[:, 1].mean()),
                    pf_rmse_x_by_epoch=r[:, 0].tolist(),
                    pf_rmse_y_by_epoch=r[:, 1].tolist(),
                    pf_runs=args.runs,
                    pf_particles=args.particles,
                    tracking_time_s=time.perf_counter() - t0,
                )
            cases[(n, R)] = entry
            print(
                f"[hernandez] {n} sensor(s), {HORIZON_NAMES[R]}-step: bound "
                f"({entry['bound_x']:.2f}, {entry['bound_y']:.2f}) m, "
                f"{entry['evaluations_per_decision']:.0f} evaluations/decision, "
                f"{entry['decision_time_s'] * 1e3:.1f} ms/decision",
                file=sys.stderr,
                flush=True,
            )
    comparison, comp_doc = None, None
    if not args.no_comparison and 1 in args.sensor_counts:
        path = sdir / "hernandez_1sensor_single.yaml"
        sc = load_scenario(path)
        seed = sc.seed if args.seed is None else args.seed
        comparison = plan_case(
            sc, search="grid", grid_size=args.grid_size, mc_samples=args.mc_samples, seed=seed
        )
        quad = planned.get((1, 1)) or plan_case(
            sc, search="quadrant", mc_samples=args.mc_samples, seed=seed
        )
        gap = np.linalg.norm(quad.paths[:, 0, [0, 2]] - comparison.paths[:, 0, [0, 2]], axis=1)
        comp_doc = {
            "sensors": 1,
            "horizon": 1,
            "grid_size": args.grid_size,
            "quadrant": {
                "bound_x": float(quad.bounds[:, 0].mean()),
                "bound_y": float(quad.bounds[:, 1].mean()),
                "mean_b_k": float(quad.bounds.max(axis=1).mean()),
                "evaluations_per_decision": float(np.mean(quad.evaluations)),
                "decision_time_s": float(np.mean(quad.decision_times)),
            },
            "grid": {
                "bound_x": float(comparison.bounds[:, 0].mean()),
                "bound_y": float(comparison.bounds[:, 1].mean()),
                "mean_b_k": float(comparison.bounds.max(axis=1).mean()),
                "evaluations_per_decision": float(np.mean(comparison.evaluations)),
                "decision_time_s": float(np.mean(comparison.decision_times)),
            },
            "path_separation_m": {"max": float(gap.max()), "final": float(gap[-1])},
            "grid_path": comparison.paths[:, 0].tolist(),
            "quadrant_path": quad.paths[:, 0].tolist(),
        }
    doc = {
        "experiment": "hernandez2004",
        "units": {"bounds": "m", "time": "s"},
        "runs": args.runs,
        "particles": args.particles,
        "cases": [cases[k] for k in sorted(cases)],
        "table2_improvement_percent": {
            str(n): dict(zip(("bound_x", "bound_y", "pf_rmse_x", "pf_rmse_y"), v, strict=True))
            for n, v in improvements(cases).items()
        },
        "search_comparison": comp_doc,
    }
    print(_fmt_table1(cases))
    print()
    print(_fmt_table2(cases))
    if comp_doc:
        q, g = comp_doc["quadrant"], comp_doc["grid"]
        print()
        print("Quadrant search vs 101x101 grid, 1 sensor single-step:")
        for name, d in (("quadrant", q), (f"grid {args.grid_size}x{args.grid_size}", g)):
            print(
                f"  {name:16s} bound ({d['bound_x']:.2f}, {d['bound_y']:.2f}) m, mean b_k "
                f"{d['mean_b_k']:.2f} m, {d['evaluations_per_decision']:.0f} evaluations and "
                f"{d['decision_time_s'] * 1e3:.1f} ms per decision"
            )
        print(
            f"  path separation: max {comp_doc['path_separation_m']['max']:.0f} m, "
            f"final {comp_doc['path_separation_m']['final']:.0f} m"
        )
    if not args.no_figures and scenario is not None:
        sc = load_scenario(sdir / "hernandez_1sensor_single.yaml")
        model = build_motion_model(sc.target.motion)
        rng = np.random.default_rng(sc.seed)
        X0 = gaussian_samples(
            np.asarray(sc.target.prior.mean), sc.target.prior.covariance(), 1000, rng
        )
        F, Q = model.transition_matrix(sc.dt), model.process_noise(sc.dt)
        X = np.concatenate([X0[None], propagate_samples(X0, F, Q, sc.steps, rng)])
        files = save_figures(Path(args.out), planned, rmse, comparison, sc, X)
        doc["figures"] = [str(f) for f in files]
        print("\nfigures: " + ", ".join(str(f) for f in files))
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(doc, indent=1))
    return doc


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``activetrack reproduce hernandez``."""
    args = _parse(sys.argv[1:] if argv is None else argv)
    run(args)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
