"""Adaptive grid refinement: add nodes only on the axis intervals where the map is wrong.

For every interval of every state axis, states are drawn with that coordinate at the
interval's midpoint (the worst place for linear interpolation) and the others random inside
the grid; the map's capacity is compared with the reference method there. An interval whose
95th-percentile error exceeds the tolerance gets its midpoint as a new node. The grid stays
rectilinear (a node added on one axis adds a hyperplane of states), so the refinement is
local per axis, not per cell: a trade that keeps the 16-corner query.
"""
from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

from ..types import AnchorState
from .accuracy import reference_predictor
from .grid import STATE_AXES, MapGrid
from .query import CapacityMap


@dataclass(frozen=True)
class IntervalError:
    axis: str
    lo: float                  # SI
    hi: float
    p95_pct: float             # NaN when no sample could be compared
    compared: int
    mismatched: int            # map and reference disagree on having a value


def interval_errors(cmap: CapacityMap, samples: int = 6, seed: int = 0,
                    reference: str = 'direct', progress: bool = False) -> list[IntervalError]:
    predictor, _ = reference_predictor(cmap, reference)
    rng = np.random.default_rng(seed)
    axes = [getattr(cmap.grid, a) for a in STATE_AXES]
    lo = np.array([a[0] for a in axes])
    hi = np.array([a[-1] for a in axes])
    phis = cmap.phis
    jobs = [(k, j) for k, a in enumerate(axes) for j in range(len(a) - 1)]
    out = []
    for k, j in tqdm(jobs, desc='intervals', unit='interval', file=sys.stderr,
                     disable=not progress):
        errs, mismatched = [], 0
        for _ in range(samples):
            s = lo + (hi - lo) * rng.random(4)
            s[k] = 0.5 * (axes[k][j] + axes[k][j + 1])
            state = AnchorState(*map(float, s))
            pull = cmap.pulls[rng.integers(len(cmap.pulls))]
            phi = float(phis[rng.integers(len(phis))])
            r = predictor.predict(state, phi, pull)
            m = cmap.query(state, phi, pull)
            if r.ok != m.ok:
                mismatched += 1
            elif r.capacity_N is not None and m.capacity_N is not None and r.capacity_N > 1e-9:
                errs.append(100.0 * abs(m.capacity_N - r.capacity_N) / r.capacity_N)
        p95 = float(np.percentile(errs, 95)) if errs else float('nan')
        out.append(IntervalError(STATE_AXES[k], float(axes[k][j]), float(axes[k][j + 1]), p95,
                                 len(errs), mismatched))
    return out


def refined_grid(grid: MapGrid, errors: list[IntervalError], tol_pct: float) -> MapGrid:
    """The grid with the midpoint of every interval whose p95 error exceeds tol_pct."""
    new = {a: list(getattr(grid, a)) for a in STATE_AXES}
    for e in errors:
        if np.isfinite(e.p95_pct) and e.p95_pct > tol_pct:
            new[e.axis].append(0.5 * (e.lo + e.hi))
    return MapGrid(**{a: np.unique(np.asarray(v, dtype=float)) for a, v in new.items()},
                   phi=grid.phi, pulls=grid.pulls)
