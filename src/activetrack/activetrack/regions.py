"""The surveillance region's rules, shared by the scenario schema and the planner's search
(:class:`activetrack.planning.search_intensity.Surveillance`), so that both say the same thing
about the same region: a rectangle ``(x_min, x_max, y_min, y_max)`` [m] on a grid of square
cells, with targets born over it (``uniform``) or entering along named ``edges``."""

from __future__ import annotations

import math
from collections.abc import Sequence

from activetrack import limits

__all__ = ["BIRTHS", "EDGES", "check_surveillance", "grid_shape"]

BIRTHS = ("uniform", "edges")
EDGES = ("west", "east", "south", "north")


def grid_shape(region: Sequence[float], cell_size: float) -> tuple[int, int]:
    """Cells along x and y: the region's sides over ``cell_size``, rounded up."""
    x0, x1, y0, y1 = region
    return (
        max(1, math.ceil((x1 - x0) / cell_size)),
        max(1, math.ceil((y1 - y0) / cell_size)),
    )


def check_surveillance(
    region: Sequence[float],
    cell_size: float,
    births: str,
    edges: Sequence[str],
    birth_speed: float,
    prefix: str = "",
) -> None:
    """Raise ``ValueError`` naming the field (after ``prefix``) unless the region is a finite
    rectangle of at most MAX_SURVEILLANCE_CELLS cells, ``births`` one of :data:`BIRTHS`,
    ``edges`` distinct names of :data:`EDGES` (one or more for ``edges`` births, none
    otherwise) and ``birth_speed`` in [0, MAX_SPEED] m/s (0 for uniform births)."""
    x0, x1, y0, y1 = (float(v) for v in region)
    if not (x0 < x1 and y0 < y1 and all(map(math.isfinite, (x0, x1, y0, y1)))):
        raise ValueError(
            f"{prefix}region must be finite [x_min, x_max, y_min, y_max] with x_min < x_max "
            f"and y_min < y_max, got {list(region)}"
        )
    if not (math.isfinite(cell_size) and cell_size > 0.0):
        raise ValueError(f"{prefix}cell_size must be > 0, got {cell_size}")
    nx, ny = grid_shape((x0, x1, y0, y1), cell_size)
    if nx * ny > limits.MAX_SURVEILLANCE_CELLS:
        raise ValueError(
            f"{prefix}cell_size {cell_size} m gives {nx} x {ny} cells over the region, more "
            f"than {limits.MAX_SURVEILLANCE_CELLS}"
        )
    if births not in BIRTHS:
        raise ValueError(f"{prefix}births must be one of {BIRTHS}, got {births!r}")
    if not (math.isfinite(birth_speed) and 0.0 <= birth_speed <= limits.MAX_SPEED):
        raise ValueError(
            f"{prefix}birth_speed must lie in [0, {limits.MAX_SPEED}] m/s, got {birth_speed}"
        )
    if births == "edges":
        bad = [e for e in edges if e not in EDGES]
        if not edges or bad or len(set(edges)) != len(edges):
            raise ValueError(
                f"{prefix}edges: births 'edges' needs one or more distinct edges of {EDGES}, "
                f"got {list(edges)}"
            )
    elif edges or birth_speed != 0.0:
        raise ValueError(
            f"{prefix}edges and {prefix}birth_speed need births 'edges' (uniform births have no "
            f"entry edge or direction), got edges {list(edges)}, birth_speed {birth_speed}"
        )
