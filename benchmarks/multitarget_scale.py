"""The scale table of ``benchmarks/multitarget.py``: our tracker step and Stone Soup's JPDA
and EHM from 3 to 1,000 targets, spread out and crowded, 10 to 1,000 false alarms per scan.

Scenes (:func:`build`): ``n`` NCV targets (10 m/s, random headings) over a square of ``cells
x cells`` radar cells of :data:`CELL` m, one stationary all-around range-bearing radar at each
cell's centre reaching :data:`REACH` cell sides (neighbours overlap a little), sigma_r 50 m,
sigma_b 0.02 rad, Pd 0.9, ``clutter`` false alarms per scan and radar on average (Poisson,
uniform in (range, bearing) over the radar's annulus), one scan per radar every 5 s.

- ``spread``: about :data:`TARGETS_PER_CELL` targets per cell, uniform over the square
  (``cells = ceil(sqrt(n / 8))``: 1 radar for 3 targets, 4 for 30, 16 for 100, 49 for 300,
  144 for 1,000);
- ``crowded``: clumps of up to :data:`CLUMP` targets (``cells = ceil(sqrt(n / 10))``), target
  k in cell ``k mod cells^2``, each clump starting inside a :data:`CLUMP_BOX` m square
  :data:`CLUMP_OFFSET` m east of its radar: gates overlap (cross-range noise 80 m, prior
  100 m), so clusters hold most of a clump.

Every target has a prior N(x0 + e, P0), e ~ N(0, P0), P0 = diag(100 m, 3 m/s)^2. Truth, scans
and priors come from ``default_rng(seed)``.

Timed per epoch (all radars' scans), after one untimed epoch of warm-up on a small scene:

- **ours**: :class:`activetrack.tracking.tracker.Tracker` ``step`` with the EKF and the
  schema's default ``tracker.tracks`` except ``max_tracks`` (:func:`max_tracks`: room for the
  clutter's tentative tracks, up to ``limits.MAX_TRACKS``; detections it leaves unstarted are
  printed beside the time) and ``oversize_cluster: prune`` (a JPDA cluster too large for its
  exact net, as the tentative tracks of 1,000 false alarms a scan chain into, loses its
  weakest gated pairs: the clusters pruned and pairs dropped are printed beside the time;
  where none is, the step is the exact JPDA's, to the bit):
  association, initiation from the clutter, M-of-N, existence, deletion, coalescence;
- **Stone Soup**: the prior tracks only (no initiation, no deletion: its association and
  update alone, so a lower bound of its tracker), per radar scan the tracks whose predicted
  position the radar sees, ``associate`` then ``PDAUpdater.update``, with ``JPDA`` (it lists
  every joint event, ``itertools.product``) or the efficient hypothesis management of Maskell
  et al. through Stone Soup's pyehm plugin (``JPDAWithEHM``, ``JPDAWithEHM2``), exact both.

Run alone (``.venv/bin/python benchmarks/multitarget_scale.py [--sizes 300 1000] [--clutter
10] [--layouts spread] [--implementations ours] [--epochs 5] [--budget 30]``) it prints those
rows of the table and ``n<N>_step_ms=<ms>`` for our step: by default the two figures of
``multitarget.py``'s last line (``n300_step_ms``, ``n1000_step_ms``: spread, clutter 10), timed
the same way, in a few minutes without Stone Soup.

Budget: each implementation gets :data:`POINT_BUDGET_S` s of wall time per point (``--quick``:
:data:`QUICK_BUDGET_S`), enforced by ``SIGALRM`` inside the epoch. A point that runs out prints
``over budget (POINT_BUDGET_S=<s> s)`` with the epochs it finished; the same implementation is
then not started on larger scenes of that layout and clutter, which print ``not run: over
budget at n=<n> (POINT_BUDGET_S=<s> s)``. Nothing is skipped without a line saying so.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import signal
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timedelta

import numpy as np

from activetrack import limits
from activetrack.data import Scan
from activetrack.filters.ekf import ExtendedKalmanFilter
from activetrack.filters.jpda import gate_probability
from activetrack.models.clutter import ClutteredSensor
from activetrack.models.fov import FieldOfView
from activetrack.models.motion import NearlyConstantVelocity
from activetrack.models.sensors import RangeBearingSensor
from activetrack.scenarios.schema import TrackManagementConfig
from activetrack.tracking.tracker import FilterSpec, Tracker, TrackPrior

LAYOUTS = ("spread", "crowded")
TARGETS_PER_CELL = 8  # spread: targets per radar cell
CLUMP = 10  # crowded: targets per clump (one clump per cell)
CLUMP_BOX = 1000.0  # m, side of the square a clump starts in
CLUMP_OFFSET = 4000.0  # m, the clump's centre east of its radar
CELL = 10_000.0  # m, side of one radar's cell
REACH = 0.75  # radar r_max in cell sides (the cell's corner is at 0.71)
R_MIN = 100.0  # m
DT = 5.0  # s between epochs
Q = 0.01  # NCV process-noise PSD, m^2/s^3
SPEED = 10.0  # m/s
PRIOR_STD = (100.0, 3.0, 100.0, 3.0)
SIGMA_R, SIGMA_B, PD = 50.0, 0.02, 0.9
POINT_BUDGET_S = 30.0  # wall time per implementation and point
QUICK_BUDGET_S = 4.0  # the same with --quick
IMPLEMENTATIONS = ("ours", "ss_jpda", "ss_ehm", "ss_ehm2")
_EPOCH = datetime(2024, 1, 1)


@dataclass
class ScaleScene:
    """One seeded scene: its radars ``(id, sensor, pv (4,), fov)``, the priors' means
    ``(n, 4)`` and covariance, truth ``(K + 1, n, 4)`` and per epoch one ``(m, 2)`` scan of
    (range, bearing) per radar."""

    n_targets: int
    layout: str
    clutter: float
    cells: int
    radars: list[tuple[str, ClutteredSensor, np.ndarray, FieldOfView]]
    prior_means: np.ndarray
    prior_cov: np.ndarray
    truth: np.ndarray
    scans: list[list[np.ndarray]]

    @property
    def detections_per_epoch(self) -> float:
        return float(np.mean([sum(len(z) for z in row) for row in self.scans]))


def build(n_targets: int, layout: str, clutter: float, seed: int = 0, steps: int = 5) -> ScaleScene:
    """The scene (module docstring) over ``steps`` epochs."""
    if layout not in LAYOUTS:
        raise ValueError(f"layout: must be one of {LAYOUTS}, got {layout!r}")
    if n_targets < 1 or steps < 1 or not clutter >= 0.0:
        raise ValueError(
            f"n_targets, steps >= 1 and clutter >= 0 required, got {n_targets}, {steps}, {clutter}"
        )
    rng = np.random.default_rng(seed)
    per_cell = TARGETS_PER_CELL if layout == "spread" else CLUMP
    cells = max(1, math.ceil(math.sqrt(n_targets / per_cell)))
    r_max = REACH * CELL
    fov = FieldOfView(0.0, 2.0 * math.pi, R_MIN, r_max)
    density = clutter / ((r_max - R_MIN) * 2.0 * math.pi)  # per m rad
    gate = TrackManagementConfig().gate_sigmas
    radars = []
    for i in range(cells):
        for j in range(cells):
            base = RangeBearingSensor(SIGMA_R, SIGMA_B, PD, R_MIN, r_max)
            pv = np.array([(i + 0.5) * CELL, 0.0, (j + 0.5) * CELL, 0.0])
            radars.append((f"radar_{i}_{j}", ClutteredSensor(base, density, gate), pv, fov))
    heading = rng.uniform(-math.pi, math.pi, n_targets)
    if layout == "spread":
        xy = rng.uniform(0.0, cells * CELL, (n_targets, 2))
    else:
        centres = np.array([[pv[0] + CLUMP_OFFSET, pv[2]] for _, _, pv, _ in radars])
        xy = centres[np.arange(n_targets) % len(radars)] + rng.uniform(
            -0.5 * CLUMP_BOX, 0.5 * CLUMP_BOX, (n_targets, 2)
        )
    x = np.column_stack([xy[:, 0], SPEED * np.cos(heading), xy[:, 1], SPEED * np.sin(heading)])
    std = np.asarray(PRIOR_STD)
    means = x + rng.standard_normal(x.shape) * std
    model = NearlyConstantVelocity(Q)
    truth, scans = [x], []
    for _ in range(steps):
        x = model.sample(x, DT, rng)
        truth.append(x)
        row = []
        for _, sensor, pv, view in radars:
            X = x[view.contains(x, pv)]
            seen = X[sensor.detect(X, pv, rng)]
            Z = np.concatenate([sensor.sample(seen, pv, rng), sensor.sample_clutter(view, rng)])
            row.append(Z[rng.permutation(len(Z))])
        scans.append(row)
    return ScaleScene(
        n_targets, layout, float(clutter), cells, radars, means, np.diag(std**2),
        np.array(truth), scans,
    )  # fmt: skip


# --- the implementations: each ``make(scene)`` gives ``step(k)`` for epoch k = 1..K --------


def ours(scene: ScaleScene) -> Callable[[int], None]:
    """Our tracker's step (module docstring); the epoch's ``Scan`` objects built beforehand."""
    model = NearlyConstantVelocity(Q)
    cfg = TrackManagementConfig(max_tracks=max_tracks(scene), oversize_cluster="prune")

    def make(x0: np.ndarray, P0: np.ndarray, t0: float) -> ExtendedKalmanFilter:
        return ExtendedKalmanFilter(model, x0, P0, t0)

    tracker = Tracker(
        model,
        "ncv",
        # with its batch constructor, as the registry gives it to ``batch`` and the node
        FilterSpec(
            "ekf", False, make, lambda X0, P0, t0: ExtendedKalmanFilter.many(model, X0, P0, t0)
        ),
        {sid: sensor for sid, sensor, _, _ in scene.radars},
        [TrackPrior(f"t{i}", m, scene.prior_cov) for i, m in enumerate(scene.prior_means)],
        known_association=False,
        management=cfg,
        planner_samples=1,
        new_track_priority=1.0,
        rng=np.random.default_rng(0),
    )
    scans = [
        [
            Scan(sid, k, k * DT, pv, Z, fov)
            for (sid, _, pv, fov), Z in zip(scene.radars, row, strict=True)
        ]
        for k, row in enumerate(scene.scans, start=1)
    ]

    def step(k: int) -> None:
        tracker.step(k, k * DT, scans[k - 1])

    step.tracker = tracker  # type: ignore[attr-defined]  # its counters, read after timing
    return step


def max_tracks(scene: ScaleScene) -> int:
    """Our tracker's ``max_tracks``: room for every target and every tentative track the
    clutter starts (each lives about 3 epochs: ``n + ceil(4 clutter) radars + 100``), at most
    the schema's :data:`activetrack.limits.MAX_TRACKS`; detections left unstarted because of
    it are printed in the table."""
    room = scene.n_targets + math.ceil(4 * scene.clutter) * len(scene.radars) + 100
    return min(room, limits.MAX_TRACKS)


def tracker_note(tracker: Tracker) -> str:
    """What our tracker reports beside its time: JPDA clusters pruned (with the pairs dropped)
    and detections left unstarted by ``max_tracks``, each when there were any."""
    notes = []
    if tracker.pruning.clusters:
        notes.append(
            f"{tracker.pruning.clusters} clusters pruned, {tracker.pruning.pairs} pairs dropped"
        )
    if tracker.not_started:
        notes.append(f"{tracker.not_started} detections not started (max_tracks)")
    return "; ".join(notes)


def _stonesoup_associator(kind: str, hypothesiser):
    if kind == "ss_jpda":
        from stonesoup.dataassociator.probability import JPDA

        return JPDA(hypothesiser=hypothesiser)
    from stonesoup.plugins.pyehm import JPDAWithEHM, JPDAWithEHM2

    cls = JPDAWithEHM if kind == "ss_ehm" else JPDAWithEHM2
    return cls(hypothesiser=hypothesiser)


def stonesoup(scene: ScaleScene, kind: str) -> Callable[[int], None]:
    """Stone Soup's association and PDA update of the prior tracks (module docstring) with
    the associator ``kind`` (``ss_jpda``, ``ss_ehm``, ``ss_ehm2``)."""
    from stonesoup.hypothesiser.probability import PDAHypothesiser
    from stonesoup.models.measurement.nonlinear import CartesianToBearingRange
    from stonesoup.models.transition.linear import (
        CombinedLinearGaussianTransitionModel,
        ConstantVelocity,
    )
    from stonesoup.predictor.kalman import ExtendedKalmanPredictor
    from stonesoup.types.angle import Bearing
    from stonesoup.types.array import StateVector
    from stonesoup.types.detection import Detection
    from stonesoup.types.state import GaussianState
    from stonesoup.types.track import Track
    from stonesoup.updater.probability import PDAUpdater

    predictor = ExtendedKalmanPredictor(
        CombinedLinearGaussianTransitionModel([ConstantVelocity(Q), ConstantVelocity(Q)])
    )
    gamma = TrackManagementConfig().gate_sigmas ** 2
    per_radar = []  # (associator, updater, pv, fov, detections per epoch)
    for r_idx, (_, sensor, pv, fov) in enumerate(scene.radars):
        mm = CartesianToBearingRange(
            ndim_state=4, mapping=(0, 2), noise_covar=np.diag([SIGMA_B**2, SIGMA_R**2]),
            translation_offset=StateVector([pv[0], pv[2]]),
        )  # fmt: skip
        updater = PDAUpdater(mm, force_symmetric_covariance=True)
        hypothesiser = PDAHypothesiser(
            predictor=predictor, updater=updater,
            clutter_spatial_density=max(sensor.clutter_density, 1e-12), prob_detect=PD,
            prob_gate=gate_probability(gamma, 2),
        )  # fmt: skip
        dets = [
            {Detection(StateVector([Bearing(b), r]), timestamp=_EPOCH + timedelta(seconds=k * DT),
                       measurement_model=mm) for r, b in row[r_idx]}
            for k, row in enumerate(scene.scans, start=1)
        ]  # fmt: skip
        per_radar.append((_stonesoup_associator(kind, hypothesiser), updater, pv, fov, dets))
    tracks = [
        Track([GaussianState(m.reshape(4, 1), scene.prior_cov, timestamp=_EPOCH)])
        for m in scene.prior_means
    ]
    F = NearlyConstantVelocity(Q).transition_matrix(DT)

    def step(k: int) -> None:
        when = _EPOCH + timedelta(seconds=k * DT)
        # Each radar gets the tracks whose position predicted to the scan it sees.
        X = np.array([np.asarray(t.state_vector, dtype=float)[:, 0] for t in tracks]) @ F.T
        for associator, updater, pv, fov, dets in per_radar:
            seen = [tracks[i] for i in np.flatnonzero(fov.contains(X, pv))]
            if not seen:
                continue
            hypotheses = associator.associate(seen, dets[k - 1], when)
            for track in seen:
                track.append(updater.update(hypotheses[track]))

    return step


# --- timing under a budget -------------------------------------------------------------------


class OverBudget(Exception):
    """The point's wall-time budget ran out."""


def _alarm(signum, frame):
    raise OverBudget


@dataclass
class PointTime:
    """One implementation at one point: the finished epochs' wall times (s) and whether the
    budget ran out (``over``), or the error it raised."""

    times: list[float]
    over: bool = False
    error: str = ""
    stopped_at: int = 0  # not started: over budget (or failed: ``error``) at this smaller n
    note: str = ""  # what the run reported (detections left unstarted, clusters pruned)
    pruned: int = 0  # ours: JPDA clusters pruned (oversize_cluster: prune)

    def cell(self, budget: float) -> str:
        if self.stopped_at and self.error:
            return f"not run: failed at n={self.stopped_at}"
        if self.stopped_at:
            return f"not run: over budget at n={self.stopped_at} (POINT_BUDGET_S={budget:g} s)"
        if self.error:
            return f"error: {self.error}"
        if not self.times:
            return f"over budget (POINT_BUDGET_S={budget:g} s)"
        text = f"{np.median(self.times) * 1e3:.1f} ms"
        if self.over:
            text += f" ({len(self.times)} epochs, then over budget (POINT_BUDGET_S={budget:g} s))"
        return text + (f" [{self.note}]" if self.note else "")


def time_epochs(step: Callable[[int], None], n_epochs: int, budget: float) -> PointTime:
    """Wall time of ``step(k)`` for k = 1..``n_epochs``, stopped by SIGALRM after ``budget`` s
    in all (main thread only)."""
    out = PointTime([])
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.setitimer(signal.ITIMER_REAL, budget)
    try:
        for k in range(1, n_epochs + 1):
            t0 = time.perf_counter()
            step(k)
            out.times.append(time.perf_counter() - t0)
    except OverBudget:
        out.over = True
    except (ValueError, RuntimeError, MemoryError) as e:
        out.error = f"{type(e).__name__}: {str(e)[:80]}"
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0.0)
        signal.signal(signal.SIGALRM, previous)
    return out


def make_step(name: str, scene: ScaleScene) -> Callable[[int], None]:
    return ours(scene) if name == "ours" else stonesoup(scene, name)


@dataclass
class ScaleRow:
    n_targets: int
    layout: str
    clutter: float
    radars: int
    detections: float
    cells: dict[str, PointTime]


def scale_table(
    sizes: list[int],
    layouts: list[str],
    clutters: list[float],
    implementations: list[str],
    budget: float,
    epochs: int,
    seed: int = 0,
    printer: Callable[[ScaleRow, float], None] | None = None,
) -> list[ScaleRow]:
    """Every point (layout, clutter, n), ``n`` in ascending order; an implementation over budget
    is not started on larger ``n`` of the same layout and clutter (its cells say so)."""
    for name in implementations:  # imports and compilation out of the timing
        scene = build(3, "spread", 10.0, seed, 1)
        time_epochs(make_step(name, scene), 1, 60.0)
    rows = []
    for layout in layouts:
        for clutter in clutters:
            stopped: dict[str, tuple[int, str]] = {}
            for n in sorted(sizes):
                scene = build(n, layout, clutter, seed, epochs)
                cells = {}
                for name in implementations:
                    if name in stopped:
                        cells[name] = PointTime(
                            [], stopped_at=stopped[name][0], error=stopped[name][1]
                        )
                        continue
                    try:
                        step = make_step(name, scene)
                    except ImportError as e:
                        cells[name] = PointTime([], error=f"not installed ({e.name})")
                        continue
                    except ValueError as e:  # a limit of ours (named in the message)
                        cells[name] = PointTime([], error=f"{type(e).__name__}: {str(e)[:120]}")
                        stopped[name] = (n, cells[name].error)
                        continue
                    cells[name] = time_epochs(step, epochs, budget)
                    tracker = getattr(step, "tracker", None)
                    if tracker is not None:
                        cells[name].note = tracker_note(tracker)
                        cells[name].pruned = tracker.pruning.clusters
                    if cells[name].over or cells[name].error:
                        stopped[name] = (n, cells[name].error)
                row = ScaleRow(
                    n, layout, clutter, len(scene.radars), scene.detections_per_epoch, cells
                )
                rows.append(row)
                if printer is not None:
                    printer(row, budget)
    return rows


def print_header(implementations: list[str], epochs: int, budget: float) -> None:
    print(
        f"# scale table: median wall time per epoch over {epochs} epochs (all radars' scans); "
        f"ours: Tracker.step (everything); Stone Soup: association + PDA update of the prior "
        f"tracks only; budget POINT_BUDGET_S={budget:g} s per implementation and point"
    )
    print(f"{'layout':<8} {'clutter':>7} {'n':>5} {'radars':>6} {'dets':>7}  "
          + "  ".join(f"{name:<12}" for name in implementations))  # fmt: skip


def print_row(row: ScaleRow, budget: float) -> None:
    cells = "  ".join(f"{row.cells[name].cell(budget):<12}" for name in row.cells)
    print(
        f"{row.layout:<8} {row.clutter:7g} {row.n_targets:5d} {row.radars:6d} "
        f"{row.detections:7.0f}  {cells}",
        flush=True,
    )


def main(argv: list[str] | None = None) -> int:
    """The chosen points of the table (module docstring), then our step's median per size."""
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[300, 1000])
    p.add_argument("--clutter", type=float, nargs="+", default=[10.0])
    p.add_argument("--layouts", nargs="+", choices=LAYOUTS, default=["spread"])
    p.add_argument("--implementations", nargs="+", choices=IMPLEMENTATIONS, default=["ours"])
    p.add_argument("--epochs", type=int, default=5, help="timed epochs per point")
    p.add_argument("--budget", type=float, default=POINT_BUDGET_S, help="POINT_BUDGET_S (s)")
    args = p.parse_args(argv)
    # The tracker's once-per-run warnings (clusters pruned, max_tracks) would come once per
    # point: what they say is in the table's notes.
    logging.getLogger("activetrack.tracking.tracker").setLevel(logging.ERROR)
    sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
    import machine  # benchmarks/machine.py, beside this script

    print(f"# {machine.describe()}")
    print_header(args.implementations, args.epochs, args.budget)
    rows = scale_table(
        args.sizes, args.layouts, sorted(args.clutter), args.implementations, args.budget,
        args.epochs, printer=print_row,
    )  # fmt: skip
    print(f"# load average {os.getloadavg()[0]:.1f}")
    if "ours" in args.implementations:  # as multitarget.py's last line: spread, lowest clutter
        figures, pruned = [], []
        for n in args.sizes:
            row = next((r for r in rows if r.n_targets == n and r.layout == "spread"), None)
            times = row.cells["ours"].times if row else []
            figures.append(
                f"n{n}_step_ms={np.median(times) * 1e3:.1f}" if times else f"n{n}_step_ms=none"
            )
            pruned.append(f"n{n} {row.cells['ours'].pruned if row else 'not run'}")
        print(f"# JPDA clusters pruned behind them (0: exact JPDA): {', '.join(pruned)}")
        print(" ".join(figures))
    return 0


if __name__ == "__main__":
    from activetrack.allocator import tune_allocator

    tune_allocator()  # as multitarget.py and the command line do
    raise SystemExit(main())
