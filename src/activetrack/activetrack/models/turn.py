"""Constant-turn model with known turn rate (Valverde sec. IV-B, eq. 30-37).

State pv = (x, xdot, y, ydot).  The continuous model (eq. 32-33) is

    d/dt (x, xdot, y, ydot) = (xdot, -omega ydot, ydot, omega xdot) + G w(t),
    G = [[0, 1, 0, 0], [0, 0, 0, 1]]^T,  E[w(t) w(s)^T] = q I_2 delta(t - s),

i.e. white-noise accelerations of PSD q on each axis, as in the NCV model.  The transition is
eq. 35 and Q is the integral eq. 37 evaluated in closed form (theta = omega T):

    Q = q [[2 d3,  c2,    0,     omega d3 ],
           [c2,    T,    -omega d3, 0     ],
           [0,    -omega d3, 2 d3,  c2    ],
           [omega d3, 0,  c2,    T        ]]

with c2 = (1 - cos theta)/omega^2 and d3 = (theta - sin theta)/omega^3 (see _turn_terms).
As omega -> 0 this tends to the NCV Q (2 d3 -> T^3/3, c2 -> T^2/2, omega d3 -> 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from activetrack.arraytypes import ArrayLike, FloatArray
from activetrack.checks import require_finite, require_nonnegative
from activetrack.models._common import check_dt
from activetrack.models._turn_terms import turn_terms
from activetrack.models.ncv import _LinearPV


@dataclass(frozen=True)
class ConstantTurn(_LinearPV):
    """Constant turn rate ``omega`` (rad/s, counter-clockwise positive), noise PSD ``q``."""

    omega: float
    q: float

    def __post_init__(self) -> None:
        omega = float(require_finite("omega", self.omega))
        object.__setattr__(self, "omega", omega)
        object.__setattr__(self, "q", require_nonnegative("q", self.q))

    def transition_matrix(self, dt: float) -> FloatArray:
        """Phi of Valverde eq. 35, (4, 4); reduces to the CV matrix at omega = 0."""
        T = check_dt(dt)
        s1, c1, _, _, _, _ = turn_terms(self.omega, T)
        c, s = np.cos(self.omega * T), np.sin(self.omega * T)
        return np.array(
            [
                [1.0, s1, 0.0, -c1],
                [0.0, c, 0.0, -s],
                [0.0, c1, 1.0, s1],
                [0.0, s, 0.0, c],
            ]
        )

    def process_noise(self, dt: float, x: ArrayLike | None = None) -> FloatArray:
        """Q of Valverde eq. 37 in closed form (module docstring), (4, 4), symmetric PSD."""
        T = check_dt(dt)
        terms = turn_terms(self.omega, T)
        c2, d3 = float(terms[2]), float(terms[3])
        wd3 = self.omega * d3
        Q = np.array(
            [
                [2 * d3, c2, 0.0, wd3],
                [c2, T, -wd3, 0.0],
                [0.0, -wd3, 2 * d3, c2],
                [wd3, 0.0, c2, T],
            ]
        )
        return self.q * Q
