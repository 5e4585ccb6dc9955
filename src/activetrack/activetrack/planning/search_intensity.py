"""The intensity of targets not yet detected over a surveillance region, and the value of
looking for them (``planner.targets.surveillance``: search versus track).

The planner keeps, on a grid of cells over the region, the PHD of the targets no sensor has
detected yet (the undetected-target intensity of Mahler's PHD filter, *Statistical
Multisource-Multitarget Information Fusion*, 2007, sec. 16.3; its split into undetected and
detected parts: Garcia-Fernandez, Williams, Granström & Svensson, "Poisson multi-Bernoulli
mixture filter", IEEE TAES 2018, eq. 21 and 35):

- prediction (the prediction step of the PMBM's undetected Poisson intensity, Garcia-Fernandez
  et al. 2018: D_{k|k-1}(x) = D_b(x) + int f(x | x') p_S D_{k-1}(x') dx', here with
  p_S = 1): the intensity already there moves by the targets' motion, then the epoch's births
  are added. ``births`` says where targets appear and how they move:

  - ``uniform`` (the default): ``birth_rate * dt`` spread uniformly over the region
    (``birth_rate * dt * A_cell / A`` per cell); the targets' motion has no stated direction,
    so the intensity stays where it was born (f the identity);
  - ``edges``: ``birth_rate * dt`` spread uniformly along the named edges of the region
    (``west``: x_min, ``east``: x_max, ``south``: y_min, ``north``: y_max; each edge's share
    its length over the named edges' total, split evenly over its cells), the targets
    entering at ``birth_speed`` [m/s] normal to their edge, inward. The intensity keeps one
    layer per edge (the undetected targets' velocity, which the edge fixes: the state of the
    PPP is position and entry edge), and f moves each layer ``birth_speed * dt`` inward per
    epoch: a cell's mass goes to the cells its shifted square overlaps, in proportion
    (a linear split between the two cells it straddles: the discretisation spreads it by
    less than a cell per epoch, the diffusion of a velocity known to within a cell per
    epoch); mass that leaves the region is dropped and counted (``left``);
- update: a look leaves a target undetected with probability 1 - Pd where it can see it, so
  each look multiplies the intensity of the cells inside its footprint (beam, field of view
  and range limits) by (1 - Pd) (the missed-detection update of the PHD, D (1 - Pd)), in
  every layer.

A detection in a look's footprint is a new target or clutter: the PMBM's update starts a new
Bernoulli per measurement z with existence r = e(z) / (e(z) + kappa(z)), e(z) = int Pd D(x)
l(z | x) dx the detection density of the undetected targets and kappa(z) the clutter density
(Garcia-Fernandez et al. 2018, the update of the undetected PPP; Williams, "Marginal multi-
Bernoulli filters", IEEE TAES 2015, its new tracks). On the grid, with a measurement z of the
position (two components), e(z) = Pd D_cell / A_cell / |det dh/dx| at the cell's centre, so
:func:`birth_odds` gives e / kappa = Pd D_cell / (A_cell kappa |det dh/dx|) per cell (D the
intensity the look saw, before its own depletion).

A search pointing's value in GOSPA units (Rahmathullah, Garcia-Fernandez & Svensson, FUSION
2017, eq. 1: c^p / alpha per missed target): the expected number of new targets it detects,
Pd times the intensity in its footprint (cells farther than c from every track: a target
near a track is that track's, not counted twice), times c^p / alpha for each of the
``epochs`` epochs they then stay found instead of missed. Nothing is tuned: c, p, alpha, Pd,
the birth rate and the number of epochs (the planner's look-ahead) are the scenario's.
Deterministic: no draw from any generator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from activetrack.angles import within_angle, wrap_angle
from activetrack.arraytypes import ArrayLike
from activetrack.checks import require_positive
from activetrack.models.clutter import ClutteredSensor
from activetrack.regions import BIRTHS, EDGES, check_surveillance, grid_shape

__all__ = [
    "BIRTHS",
    "EDGES",
    "Surveillance",
    "UndetectedIntensity",
    "birth_odds",
    "footprint",
    "footprints",
    "search_bearings",
    "search_value",
]


# each edge's (grid axis, direction inward): the grid is (nx, ny), x along axis 0
_INWARD = {"west": (0, 1), "east": (0, -1), "south": (1, 1), "north": (1, -1)}


@dataclass(frozen=True)
class Surveillance:
    """The region ``(x_min, x_max, y_min, y_max)`` [m] where new targets appear at
    ``birth_rate`` [targets / s], on a grid of ``cell_size`` [m] square cells; ``births``
    (one of :data:`BIRTHS`) where: over the region, or along its ``edges`` (names from
    :data:`EDGES`) moving inward at ``birth_speed`` [m/s] (module docstring)."""

    region: tuple[float, float, float, float]
    birth_rate: float
    cell_size: float
    births: str = "uniform"
    edges: tuple[str, ...] = ()
    birth_speed: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.birth_rate) and self.birth_rate >= 0.0):
            raise ValueError(f"surveillance.birth_rate must be >= 0, got {self.birth_rate}")
        require_positive("surveillance.cell_size", self.cell_size)
        check_surveillance(
            self.region,
            self.cell_size,
            self.births,
            self.edges,
            self.birth_speed,
            prefix="surveillance.",
        )

    @property
    def shape(self) -> tuple[int, int]:
        """Cells along x and y (the region's sides over ``cell_size``, rounded up)."""
        return grid_shape(self.region, self.cell_size)


class UndetectedIntensity:
    """The undetected-target intensity over the region's cells, centres ``xy`` ``(N, 2)``
    (x-major: cell (i, j) is row i ny + j), kept in ``layers`` ``(L, N)`` [expected targets
    per cell]: one layer for uniform births, one per entry edge for births at edges (module
    docstring); ``intensity`` ``(N,)`` their sum. Starts empty; ``left`` counts the expected
    targets the prediction moved out of the region."""

    def __init__(self, surveillance: Surveillance, dt: float):
        require_positive("dt", dt)
        self.surveillance = surveillance
        self.dt = dt
        nx, ny = surveillance.shape
        x0, x1, y0, y1 = surveillance.region
        xs = x0 + (np.arange(nx) + 0.5) * (x1 - x0) / nx
        ys = y0 + (np.arange(ny) + 0.5) * (y1 - y0) / ny
        X, Y = np.meshgrid(xs, ys, indexing="ij")
        self.xy = np.stack([X.ravel(), Y.ravel()], axis=-1)
        self.birth = self._births(surveillance, dt)
        self.layers = np.zeros_like(self.birth)
        # the shift of each layer along its axis per epoch, in cells (signed); None: no drift
        steps = ((x1 - x0) / nx, (y1 - y0) / ny)
        self.shifts = (
            tuple(
                (
                    _INWARD[e][0],
                    _INWARD[e][1] * surveillance.birth_speed * dt / steps[_INWARD[e][0]],
                )
                for e in surveillance.edges
            )
            if surveillance.births == "edges" and surveillance.birth_speed > 0.0
            else None
        )
        self.left = 0.0

    @staticmethod
    def _births(surveillance: Surveillance, dt: float) -> np.ndarray:
        """The births of one epoch ``(L, N)`` (module docstring)."""
        nx, ny = surveillance.shape
        total = surveillance.birth_rate * dt
        if surveillance.births == "uniform":
            return np.full((1, nx * ny), total / (nx * ny))
        x0, x1, y0, y1 = surveillance.region
        length = {"west": y1 - y0, "east": y1 - y0, "south": x1 - x0, "north": x1 - x0}
        named = sum(length[e] for e in surveillance.edges)
        out = np.zeros((len(surveillance.edges), nx, ny))
        for layer, e in zip(out, surveillance.edges, strict=True):  # at most four edges
            share = total * length[e] / named
            if e in ("west", "east"):
                layer[0 if e == "west" else -1, :] = share / ny
            else:
                layer[:, 0 if e == "south" else -1] = share / nx
        return out.reshape(len(surveillance.edges), nx * ny)

    @property
    def intensity(self) -> np.ndarray:
        """The intensity ``(N,)`` summed over the layers (the one layer itself if only one)."""
        return self.layers[0] if self.layers.shape[0] == 1 else self.layers.sum(axis=0)

    def predict(self) -> None:
        """One epoch: the layers drift (``shifts``; mass leaving the region is dropped and
        added to ``left``), then D <- D + the epoch's births."""
        if self.shifts is not None:
            nx, ny = self.surveillance.shape
            grids = self.layers.reshape(-1, nx, ny)
            moved = np.stack(
                [_shift(g, axis, s) for g, (axis, s) in zip(grids, self.shifts, strict=True)]
            )
            self.left += float(grids.sum() - moved.sum())
            self.layers = moved.reshape(self.layers.shape)
        self.layers = self.layers + self.birth

    def look(self, inside: ArrayLike, pd: float) -> None:
        """A look that detects with ``pd`` in the cells ``inside`` (bool ``(N,)``): D <- D (1 -
        pd) there (the PHD's missed-detection update), in every layer."""
        if not 0.0 <= pd <= 1.0:
            raise ValueError(f"pd must lie in [0, 1], got {pd}")
        inside = np.asarray(inside, dtype=bool)
        self.layers = np.where(inside, self.layers * (1.0 - pd), self.layers)

    @property
    def cell_area(self) -> float:
        """A cell's area [m^2]."""
        nx, ny = self.surveillance.shape
        x0, x1, y0, y1 = self.surveillance.region
        return (x1 - x0) * (y1 - y0) / (nx * ny)

    def cell_of(self, xy: ArrayLike) -> np.ndarray:
        """The cell ``(M,)`` of each position ``(M, 2)``, -1 for a position farther than one
        cell outside the region (one inside that margin: the nearest cell; a target entering
        at an edge is detected within a cell of it)."""
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        nx, ny = self.surveillance.shape
        x0, x1, y0, y1 = self.surveillance.region
        fx = (xy[:, 0] - x0) / (x1 - x0) * nx
        fy = (xy[:, 1] - y0) / (y1 - y0) * ny
        inside = (fx >= -1.0) & (fx < nx + 1.0) & (fy >= -1.0) & (fy < ny + 1.0)
        ix = np.clip(np.floor(fx), 0, nx - 1).astype(int)
        iy = np.clip(np.floor(fy), 0, ny - 1).astype(int)
        return np.where(inside, ix * ny + iy, -1)

    def uncovered(self, track_xy: ArrayLike, cutoff: float) -> np.ndarray:
        """Cells farther than ``cutoff`` from every track position ``(T, 2)``: bool ``(N,)``."""
        t = np.asarray(track_xy, dtype=float).reshape(-1, 2)
        if t.shape[0] == 0:
            return np.ones(self.xy.shape[0], dtype=bool)
        d2 = ((self.xy[:, None, :] - t[None, :, :]) ** 2).sum(axis=-1)
        return np.all(d2 > cutoff * cutoff, axis=1)


def _shift(grid: np.ndarray, axis: int, cells: float) -> np.ndarray:
    """``grid`` ``(nx, ny)`` moved ``cells`` (signed, fractional) along ``axis``: a cell's mass
    goes (1 - f) to the cell n on and f to the cell n + 1 on (n, f the integer and fractional
    parts of |cells|, towards its sign); what passes the grid's end is dropped."""
    n, f = divmod(abs(cells), 1.0)
    sign = 1 if cells >= 0 else -1
    return (1.0 - f) * _roll_out(grid, axis, sign * int(n)) + f * _roll_out(
        grid, axis, sign * (int(n) + 1)
    )


def _roll_out(grid: np.ndarray, axis: int, k: int) -> np.ndarray:
    """``grid`` moved ``k`` whole cells along ``axis`` (signed), zeros shifted in, the cells
    moved past the end dropped."""
    out = np.zeros_like(grid)
    m = grid.shape[axis]
    if abs(k) >= m:
        return out
    src = [slice(None)] * grid.ndim
    dst = [slice(None)] * grid.ndim
    src[axis] = slice(0, m - k) if k >= 0 else slice(-k, m)
    dst[axis] = slice(k, m) if k >= 0 else slice(0, m + k)
    out[tuple(dst)] = grid[tuple(src)]
    return out


def footprint(
    sensor: ClutteredSensor, xy: ArrayLike, pv: ArrayLike, bearing: float | None
) -> np.ndarray:
    """The cells ``(N, 2)`` a look sees, bool ``(N,)``: inside the sensor's range limits and
    fixed field of view from pv ``(4,)`` and, for a beam, within half its ``beam_width`` of
    ``bearing`` (None: no beam)."""
    if sensor.beam_width is None:
        return footprints(sensor, xy, pv, np.zeros(1))[0]
    if bearing is None:
        raise ValueError("bearing: a beam's look needs the bearing it points at")
    return footprints(sensor, xy, pv, np.array([bearing], dtype=float))[0]


def footprints(
    sensor: ClutteredSensor, xy: ArrayLike, pv: ArrayLike, bearings: ArrayLike
) -> np.ndarray:
    """:func:`footprint` of a look at each of ``bearings`` ``(J,)``, bool ``(J, N)`` (the
    range limits and field of view worked out once; without a beam every row is the same)."""
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    pv = np.asarray(pv, dtype=float)
    cells = np.zeros((xy.shape[0], 4))
    cells[:, 0], cells[:, 2] = xy[:, 0], xy[:, 1]
    inside = np.asarray(sensor.in_range(cells, pv), dtype=bool)
    b = cell_bearings(xy, pv)
    if sensor.fov_width is not None:
        heading = math.atan2(pv[3], pv[1])
        inside &= np.abs(wrap_angle(b - heading - sensor.fov_centre)) <= 0.5 * sensor.fov_width
    bearings = np.asarray(bearings, dtype=float).reshape(-1)
    if sensor.beam_width is None:
        return np.broadcast_to(inside, (len(bearings), len(inside))).copy()
    return inside[None, :] & within_angle(b, bearings, 0.5 * sensor.beam_width)


def cell_bearings(xy: np.ndarray, pv: np.ndarray) -> np.ndarray:
    """Bearings ``(N,)`` of cell centres ``(N, 2)`` from a sensor at pv ``(4,)``."""
    return np.arctan2(xy[:, 1] - pv[2], xy[:, 0] - pv[0])


def search_bearings(xy: ArrayLike, pv: ArrayLike, beam_width: float) -> np.ndarray:
    """Bearings ``(J,)`` one ``beam_width`` apart that cover the cells ``(N, 2)`` as seen from
    pv ``(4,)``: the cells' bearings fill the circle but for its largest gap between
    neighbours; the arc left, of length a, takes ceil(a / w) pointings (at least one), centred
    on it; a largest gap under one beam width: all around, ceil(2 pi / w)."""
    require_positive("beam_width", beam_width)
    xy = np.asarray(xy, dtype=float).reshape(-1, 2)
    b = np.sort(cell_bearings(xy, np.asarray(pv, dtype=float)))
    gaps = np.diff(np.concatenate([b, [b[0] + 2.0 * math.pi]]))
    g = int(np.argmax(gaps))
    if gaps[g] < beam_width:
        n = math.ceil(2.0 * math.pi / beam_width)
        return np.asarray(wrap_angle(b[0] + beam_width * np.arange(n)), dtype=float)
    start = b[(g + 1) % len(b)]  # the arc runs from after the gap round to b[g]
    arc = 2.0 * math.pi - float(gaps[g])
    n = max(1, math.ceil(arc / beam_width - 1e-9))
    offsets = 0.5 * arc + beam_width * (np.arange(n) - 0.5 * (n - 1))
    return np.asarray(wrap_angle(start + offsets), dtype=float)


def birth_odds(
    sensor: ClutteredSensor, u: UndetectedIntensity, pv: ArrayLike, seen: ArrayLike
) -> np.ndarray:
    """e / kappa ``(N,)`` in each cell of a look from pv ``(4,)`` that saw the cells ``seen``
    (bool ``(N,)``), 0 elsewhere (module docstring): the odds that one detection there is a
    target not yet detected rather than clutter, for the intensity ``u.intensity`` the look
    saw. Needs a sensor whose measurement fixes a position (two components; a bearing alone
    starts no track); without clutter the odds are infinite where the intensity is not 0."""
    seen = np.asarray(seen, dtype=bool)
    out = np.zeros(len(seen))
    D = u.intensity  # summed over the layers once
    cells = np.flatnonzero(seen & (D > 0.0))
    if cells.size == 0:
        return out
    pv = np.asarray(pv, dtype=float)
    x = np.zeros((cells.size, 4))
    x[:, 0], x[:, 2] = u.xy[cells, 0], u.xy[cells, 1]
    H = np.asarray(sensor.jacobian(x, pv), dtype=float)
    if H.shape[-2] != 2:
        raise ValueError(
            f"sensor: birth odds need a measurement of the position (2 components), got "
            f"{H.shape[-2]}"
        )
    det = np.abs(np.linalg.det(H[..., [0, 2]]))
    e = float(sensor.pd) * D[cells] / u.cell_area
    kappa = float(sensor.clutter_density) * det
    with np.errstate(divide="ignore"):
        out[cells] = np.where(kappa > 0.0, e / np.where(kappa > 0.0, kappa, 1.0), np.inf)
    return out


def search_value(
    intensity: ArrayLike, footprint: ArrayLike, pd: float, cardinality: float, epochs: int
) -> np.ndarray:
    """The GOSPA^p a look saves ``(...)``: Pd Lambda c^p / alpha per epoch for ``epochs``
    epochs, Lambda = sum of ``intensity`` ``(N,)`` over its ``footprint`` (bool ``(..., N)``:
    the cells it sees, uncovered by tracks); ``cardinality`` = c^p / alpha (module
    docstring)."""
    if epochs < 1:
        raise ValueError(f"epochs must be >= 1, got {epochs}")
    lam = np.asarray(footprint, dtype=float) @ np.asarray(intensity, dtype=float)
    return pd * lam * cardinality * epochs
