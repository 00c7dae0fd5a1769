"""How well a described map reproduces the live solver between its nodes, and where to refine it.

The reference is the live PosedAnchorSolver on the posed description with the map's medium, RFT
model, twist count and space (reference_solver); answers are compared as for robot maps
(accuracy.py's MapComparison, refine.py's IntervalError): `rftgls map accuracy --anchor` and
`rftgls map refine --anchor`.
"""
from __future__ import annotations

import sys

import numpy as np

from ..posed import PosedAnchorResult
from ..types import Status
from .described import DescribedGrid, DescribedMap, check_identity, map_medium


def reference_solver(cmap: DescribedMap, desc, reference: str = 'direct'):
    """The live PosedAnchorSolver a described map is checked against: `reference` method, the
    map's medium, RFT model, twist count and space (the description must be the map's own)."""
    from ..posed import PosedAnchorSolver
    check_identity(cmap, desc)
    at = cmap.data.attrs
    return PosedAnchorSolver(map_medium(cmap.data), model=str(at['rft_model']),
                             method=reference, n_twists=int(at['n_twists']),
                             space=str(at['space']))


def _live(sm, desc, values: dict[str, float], phi: float, pull: str) -> PosedAnchorResult:
    """The reference answer at a state, with the build's rule off the physical range."""
    if desc.violations(values):
        return PosedAnchorResult(Status.INVALID_INPUT, sm.method, sm.space, reason='not_a_pose')
    return sm.solve(desc.pose(values, pull), phi, 0.0)


def described_accuracy(cmap: DescribedMap, desc, samples: int = 20, seed: int = 0,
                       reference: str = 'direct', progress: bool = False):
    """maps/accuracy.py's AccuracyReport for a described map: its answers against the live
    `reference` on the description at maps/accuracy.py's sample_states and the midpoints between the
    stored pull angles, every pull. Errors where both have a value; `status_mismatch` where
    one has (map_conservative: the map is the one without)."""
    from tqdm import tqdm

    from .accuracy import MapComparison, sample_states
    sm = reference_solver(cmap, desc, reference)
    g = cmap.grid
    if len(g.phi) < 2:
        raise ValueError('the map has one pull angle: no midpoints to check')
    phis = 0.5 * (g.phi[:-1] + g.phi[1:])
    states = sample_states(g, samples, seed)
    comp = MapComparison()
    for s in tqdm(states, unit='state', file=sys.stderr, desc='accuracy', disable=not progress):
        values = dict(zip(g.names, map(float, s)))
        for pull in g.pulls:
            for phi in phis.tolist():
                comp.add(cmap.query(values, phi, pull, desc.sha256),
                         _live(sm, desc, values, phi, pull))
    return comp.report(reference, len(states))


def described_interval_errors(cmap: DescribedMap, desc, samples: int = 6, seed: int = 0,
                              reference: str = 'direct', progress: bool = False) -> list:
    """maps/refine.py's IntervalError per interval of every state axis of a described map:
    `samples` states with that coordinate at the interval's midpoint, the others random in
    the grid, a random stored pull and pull angle; p95 of |map - reference| in %."""
    from tqdm import tqdm

    from .refine import IntervalError
    sm = reference_solver(cmap, desc, reference)
    g = cmap.grid
    rng = np.random.default_rng(seed)
    lo = np.array([a[0] for a in g.axes])
    hi = np.array([a[-1] for a in g.axes])
    jobs = [(k, j) for k, a in enumerate(g.axes) for j in range(len(a) - 1)]
    out = []
    for k, j in tqdm(jobs, desc='intervals', unit='interval', file=sys.stderr,
                     disable=not progress):
        errs, mismatched = [], 0
        for _ in range(samples):
            s = lo + (hi - lo) * rng.random(len(g.axes))
            s[k] = 0.5 * (g.axes[k][j] + g.axes[k][j + 1])
            values = dict(zip(g.names, map(float, s)))
            pull = g.pulls[int(rng.integers(len(g.pulls)))]
            phi = float(g.phi[int(rng.integers(len(g.phi)))])
            r = _live(sm, desc, values, phi, pull)
            m = cmap.query(values, phi, pull, desc.sha256)
            if r.ok != m.ok:
                mismatched += 1
            elif r.capacity_N is not None and m.capacity_N is not None and r.capacity_N > 1e-9:
                errs.append(100.0 * abs(m.capacity_N - r.capacity_N) / r.capacity_N)
        p95 = float(np.percentile(errs, 95)) if errs else float('nan')
        out.append(IntervalError(g.names[k], float(g.axes[k][j]), float(g.axes[k][j + 1]), p95,
                                 len(errs), mismatched))
    return out


def refined_described_grid(grid: DescribedGrid, errors: list, tol_pct: float) -> DescribedGrid:
    """The grid with the midpoint of every interval whose p95 error exceeds tol_pct."""
    new = {n: list(a) for n, a in zip(grid.names, grid.axes)}
    for e in errors:
        if np.isfinite(e.p95_pct) and e.p95_pct > tol_pct:
            new[e.axis].append(0.5 * (e.lo + e.hi))
    return DescribedGrid(grid.names, grid.units,
                         tuple(np.unique(np.asarray(new[n], dtype=float)) for n in grid.names),
                         grid.phi, grid.pulls)
