"""The expected GOSPA of every confirmed track along a rollout: a :class:`HorizonStage` of one
leg whose candidates are scored over ``R`` epochs (``planner.targets.objective: gospa``).

The search looks one leg deep (the candidate manoeuvres of the optimised platform to k+1);
from there the base policy plays out to k+R: every platform holds course (straight on at its
k+1 velocity) and every beam keeps its track (a rollout, Bertsekas, *Dynamic Programming and
Optimal Control*, vol. I, sec. 6.4: the candidates cost C R evaluations instead of C^R). At
each leg r and track t:

- the prediction P^-: the PCRLB's (Hernandez eq. 3, J_Z of eq. 8 with the IRF of Niu, Willett
  & Bar-Shalom 2001) or the MRE's (Ramdaras eq. 23) before the leg's looks;
- each sensor serving t detects it with chance Pd I_range I_fov c (c: the probability that a
  beam pointed at the prediction holds the target, after the unsuccessful looks since the last
  hit, :meth:`activetrack.planning.assignment.MissedLooks.after`; 1 without a beam), and its
  information counts with the same c (its J_Z times c; in eq. 23's bracket the IRF times c);
- the hold probability and the split of expected GOSPA^p follow
  :mod:`activetrack.planning.expected_gospa` with the spreads of P^- and of the update.

The stage's "state" is that split summed over the legs, ``(..., T, 3)`` (localisation, missed,
false), which :class:`activetrack.planning.objective.ExpectedGospaTerm` weighs.

Search versus track (:class:`FirstLegSearch`, ``planner.targets.surveillance``): on the first
leg each beam may search instead of looking at its track, as the beams' assignment at k+1 may
choose (:mod:`activetrack.planning.search_intensity`). Its best search pointing from where the
candidate puts it saves v (Pd times the undetected intensity it sees times c^p / alpha, for the
look-ahead's epochs); the beam searches where that beats its track's service, w_t (split_t
without the beam's first look - split_t) < v, and the state gains one row, the region's, whose
missed term is -v (the missed targets found: a saving). So a manoeuvre is worth what it does
to the tracks and to the search (e.g. from farther off the region spans fewer beam widths and a
look covers more of it). A beam that shares its track with another sensor keeps serving it
here (their choice would be joint).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import cast

import numpy as np

from activetrack.angles import wrap_angle
from activetrack.bounds.mre import mre_update
from activetrack.bounds.pcrlb import covariance_bound, predicted_information
from activetrack.models.clutter import ClutteredSensor
from activetrack.planning.assignment import MissedLooks, beam_coverage
from activetrack.planning.expected_gospa import (
    GospaWeights,
    hit_probability,
    hold_update,
    position_spread,
    track_split,
)

__all__ = ["FirstLegSearch", "GospaRollout", "Look", "in_view", "look_factors", "straight_on"]


def in_view(sensor: ClutteredSensor, x: np.ndarray, pv: np.ndarray) -> np.ndarray:
    """1.0 where target ``x`` ``(4,)`` is inside the fixed field of view from sensor pvs
    ``(..., 4)`` (heading of their velocity), else 0.0 ``(...)``; or targets ``(..., 4)`` from
    one pv ``(4,)``."""
    if sensor.fov_width is None:
        return np.ones(np.broadcast_shapes(np.shape(x), pv.shape)[:-1])
    heading = np.arctan2(pv[..., 3], pv[..., 1])
    bearing = np.arctan2(x[..., 2] - pv[..., 2], x[..., 0] - pv[..., 0])
    off = wrap_angle(bearing - heading - sensor.fov_centre)
    return (np.abs(off) <= 0.5 * sensor.fov_width).astype(float)


def look_factors(
    sensor: ClutteredSensor, x: np.ndarray, pv: np.ndarray, P: np.ndarray, missed: MissedLooks
) -> tuple[np.ndarray, np.ndarray]:
    """(I_range I_fov, c) ``(...)`` of a look at a target predicted at x ``(4,)`` with P
    ``(..., 4, 4)`` from pvs ``(..., 4)``: c the beam's coverage after ``missed`` (1 without a
    beam)."""
    inside = np.asarray(sensor.in_range(x, pv), dtype=float) * in_view(sensor, x, pv)
    if sensor.beam_width is None:
        return inside, np.ones_like(inside)
    c = missed.after(beam_coverage(sensor.beam_width, x, P, pv), P)
    return inside, c


def straight_on(pv: np.ndarray, legs: int, dt: float) -> np.ndarray:
    """pvs ``(legs, ..., 4)`` from pv ``(..., 4)`` at its velocity: the platform holding
    course after its first leg (the rollout's base policy)."""
    pv = np.asarray(pv, dtype=float)
    step = np.zeros_like(pv)
    step[..., 0], step[..., 2] = pv[..., 1] * dt, pv[..., 3] * dt
    return np.stack([pv + r * step for r in range(legs)])


@dataclass(frozen=True)
class Look:
    """A sensor on a platform that is not being optimised: its model, the tracks it serves
    ``(T,)`` and its pvs over the legs ``(L, 4)``."""

    model: ClutteredSensor
    serves: np.ndarray
    path: np.ndarray


@dataclass(frozen=True)
class FirstLegSearch:
    """Search versus track on the rollout's first leg (module docstring): ``values[i]`` of
    sensor i (the ``looks`` first, then ``own``) maps its pvs ``(..., 4)`` to the GOSPA^p its
    best search pointing saves ``(...)`` (None: it does not search); ``priorities`` ``(T,)``
    the tracks' weights in the objective."""

    values: tuple[Callable[[np.ndarray], np.ndarray] | None, ...]
    priorities: np.ndarray


@dataclass
class GospaRollout:
    """The stage (module docstring). ``cost_kind`` "pcrlb" (state0: J at k ``(T, 4, 4)``,
    samples per track ``(L, M, 4)``) or "mre" (state0: P_{k+1|k} ``(T, 4, 4)``); ``x``
    ``(L, T, 4)`` the CV predictions; ``looks`` the other platforms' sensors; ``own`` the
    optimised platform's sensors and the tracks each serves; ``missed`` ``(T,)`` the
    unsuccessful looks since each track's last hit, ``existence`` ``(T,)``; ``search`` the
    beams' search on the first leg (None: none; with it the state has the region's row after
    the tracks', ``(..., T + 1, 3)``)."""

    cost_kind: str  # planner.cost
    F: np.ndarray
    Q: np.ndarray
    x: np.ndarray
    samples: list[np.ndarray]
    looks: tuple[Look, ...]
    own: tuple[tuple[ClutteredSensor, np.ndarray], ...]
    missed: tuple[MissedLooks, ...]
    existence: np.ndarray
    weights: GospaWeights
    dt: float
    search: FirstLegSearch | None = None

    def prepare(self, state: np.ndarray, level: int) -> np.ndarray:
        if level != 0:
            raise ValueError("a rollout stage is searched one leg deep (horizon 1)")
        return state

    def advance(self, state0: np.ndarray, level: int, pv: np.ndarray) -> np.ndarray:
        """The split ``(..., T, 3)`` summed over the L legs, the optimised platform at pvs
        ``(..., 4)`` at k+1 and straight on after."""
        L, T = self.x.shape[0], self.x.shape[1]
        own_path = straight_on(pv, L, self.dt)
        shape = (*np.shape(pv)[:-1], 3)  # a track no candidate changes still gets their axes
        out = [np.broadcast_to(self._track(t, state0[t], own_path), shape) for t in range(T)]
        if self.search is None:
            return np.stack(out, axis=-2)
        return np.stack(self._search_first(state0, own_path, out, shape), axis=-2)

    def _search_first(
        self,
        state0: np.ndarray,
        own_path: np.ndarray,
        out: list[np.ndarray],
        shape: tuple[int, ...],
    ) -> list[np.ndarray]:
        """The tracks' splits ``out`` with each beam searching on the first leg where that
        scores better, and the region's row ``(..., 3)`` appended (module docstring)."""
        search = cast(FirstLegSearch, self.search)
        serves = [k.serves for k in self.looks] + [serves for _, serves in self.own]
        paths = [k.path for k in self.looks] + [own_path for _ in self.own]
        found = np.zeros(shape[:-1])
        for i, value in enumerate(search.values):
            if value is None:
                continue
            v = np.asarray(value(paths[i][0]), dtype=float)
            tracks = np.flatnonzero(serves[i])
            if tracks.size == 0:  # serving no track, the beam searches
                found = found + v
                continue
            t = int(tracks[0])
            if tracks.size > 1 or sum(bool(s[t]) for s in serves) > 1:
                continue  # shared with another sensor: keeps serving (module docstring)
            alt = np.broadcast_to(self._track(t, state0[t], own_path, skip=i), shape)
            w = float(search.priorities[t])
            better = w * alt.sum(axis=-1) - v < w * out[t].sum(axis=-1)
            out[t] = np.where(better[..., None], alt, out[t])
            found = found + np.where(better, v, 0.0)
        region = np.zeros(shape)
        region[..., 1] = -found
        return [*out, region]

    def _track(
        self, t: int, state: np.ndarray, own_path: np.ndarray, skip: int | None = None
    ) -> np.ndarray:
        """Track t's split summed over the legs ``(..., 3)``; ``state`` its J at k (pcrlb) or
        P_{k+1|k} (mre), updated in turn (J after the leg's looks, P before them); sensor
        ``skip`` (the looks first, then own) does not look at it on the first leg."""
        pcrlb = self.cost_kind == "pcrlb"
        total: np.ndarray | float = 0.0
        hold: np.ndarray | float = 1.0
        S = np.asarray(state, dtype=float)
        for r in range(self.x.shape[0]):
            x = self.x[r, t]
            if pcrlb:
                S = predicted_information(S, self.F, self.Q)
            P_minus = covariance_bound(S) if pcrlb else S
            looking = [(k.model, k.serves, k.path[r]) for k in self.looks]
            looking += [(model, serves, own_path[r]) for model, serves in self.own]
            sensors = [
                (model, at)
                for i, (model, serves, at) in enumerate(looking)
                if serves[t] and not (r == 0 and i == skip)
            ]
            hits = []
            for model, at in sensors:
                inside, c = look_factors(model, x, at, P_minus, self.missed[t])
                hits.append(float(model.pd) * inside * c)
                if pcrlb:
                    S = S + c[..., None, None] * model.fisher_information(self.samples[t][r], at)
                else:
                    d = model.planned_information_factor(x, at, S) * inside * c
                    S = mre_update(S, model.jacobian(x, at), model.R, d)
            q = hit_probability(np.stack(np.broadcast_arrays(*hits), axis=-1)) if hits else 0.0
            P_plus = covariance_bound(S) if pcrlb else S
            hold = hold_update(hold, q, position_spread(P_minus), self.weights.c)
            split = track_split(self.existence[t], hold, position_spread(P_plus), self.weights)
            total = total + split
            if not pcrlb:
                S = self.F @ S @ self.F.T + self.Q
        return np.asarray(total)
