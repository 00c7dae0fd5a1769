"""How well a map reproduces the model between its nodes: map answers vs. a reference method.

Sample states (SI): `samples` cell centres (chosen at random, seeded, among all cells) and
`samples` uniformly random states inside the grid; pull angles are the midpoints between the
stored angles (the worst place for linear interpolation in phi). Each state is solved by the
reference RobotPredictor for every pull orientation of the map.

Reference: 'direct' (root-finding, the project's ground truth). If that method cannot be
built (not finished yet), the report falls back to the map's own method at the map's twist
count, which measures the interpolation error alone, and says so in `note`.

Errors over answers where BOTH have a value: capacity |map - ref| in N and in % of ref (ref
> 1e-9 N), slip-twist angle between the unit scaled twists in deg. Answers where exactly one
side has a value are counted in `status_mismatch` (the map is conservative when it is the
side without a value).
"""
from __future__ import annotations

import sys
from dataclasses import asdict, dataclass

import numpy as np
from tqdm import tqdm

from ..predictor.live import RobotPredictor
from ..robots.presets import get_robot
from ..types import AnchorState, Status
from .build import spec_from_map
from .query import CapacityMap


@dataclass(frozen=True)
class ErrorStats:
    mean: float
    p95: float
    worst: float

    @classmethod
    def of(cls, x: np.ndarray) -> 'ErrorStats':
        x = np.asarray(x, dtype=float)
        if x.size == 0:
            return cls(float('nan'), float('nan'), float('nan'))
        return cls(float(np.mean(x)), float(np.percentile(x, 95)), float(np.max(x)))


@dataclass(frozen=True)
class AccuracyReport:
    reference: str
    n_states: int
    n_compared: int
    status_mismatch: int
    map_conservative: int          # mismatches where the map has no value and the ref has one
    capacity_N: ErrorStats
    capacity_pct: ErrorStats
    twist_deg: ErrorStats
    note: str = ''
    capacity_over_N_worst: float = float('nan')   # largest (map - reference), N: above it

    def to_dict(self) -> dict:
        return asdict(self)


class MapComparison:
    """Accumulates map answers against reference answers at the same (state, pull, phi) and
    makes the AccuracyReport: a status mismatch is counted (conservative when the reference has
    a value and the map has none); where both have a value and a slip twist, the capacity error
    (N, % of the reference), the twist angle (deg) and the signed excess map - reference."""

    def __init__(self) -> None:
        self.cap_err: list[float] = []
        self.pct_err: list[float] = []
        self.ang_err: list[float] = []
        self.over: list[float] = []
        self.mismatch = 0
        self.conservative = 0

    def add(self, m, r) -> None:
        """m, r: CapacityResult-like answers of the map and of the reference."""
        if m.ok != r.ok:
            self.mismatch += 1
            self.conservative += int(r.ok and not m.ok)
            return
        if (m.capacity_N is None or r.capacity_N is None or m.slip_twist_scaled is None
                or r.slip_twist_scaled is None):
            return
        d = abs(m.capacity_N - r.capacity_N)
        self.over.append(m.capacity_N - r.capacity_N)
        self.cap_err.append(d)
        if r.capacity_N > 1e-9:
            self.pct_err.append(100.0 * d / r.capacity_N)
        cosang = float(np.clip(np.dot(m.slip_twist_scaled, r.slip_twist_scaled), -1, 1))
        self.ang_err.append(float(np.degrees(np.arccos(cosang))))

    def report(self, reference: str, n_states: int, note: str = '') -> AccuracyReport:
        return AccuracyReport(reference=reference, n_states=n_states,
                              n_compared=len(self.cap_err), status_mismatch=self.mismatch,
                              map_conservative=self.conservative,
                              capacity_N=ErrorStats.of(np.asarray(self.cap_err)),
                              capacity_pct=ErrorStats.of(np.asarray(self.pct_err)),
                              twist_deg=ErrorStats.of(np.asarray(self.ang_err)), note=note,
                              capacity_over_N_worst=(float(max(self.over)) if self.over
                                                     else float('nan')))


def sample_states(grid, samples: int, seed: int = 0) -> np.ndarray:
    """(M, n) states (SI, the grid's axis order; n = 4 for a robot map, a described map's own
    variables otherwise): up to `samples` random cell centres, then `samples` uniformly random
    states inside the grid."""
    rng = np.random.default_rng(seed)
    axes = grid.axes
    n_cells = [len(a) - 1 for a in axes]
    total = int(np.prod(n_cells))
    pick = rng.choice(total, size=min(samples, total), replace=False)
    idx = np.stack(np.unravel_index(np.sort(pick), n_cells), axis=1)
    centres = np.column_stack([0.5 * (a[idx[:, d]] + a[idx[:, d] + 1])
                               for d, a in enumerate(axes)])
    lo = np.array([a[0] for a in axes])
    hi = np.array([a[-1] for a in axes])
    randoms = lo + (hi - lo) * rng.random((samples, len(axes)))
    return np.vstack([centres, randoms])


def reference_predictor(cmap: CapacityMap, reference: str = 'direct') -> tuple[RobotPredictor, str]:
    spec = spec_from_map(cmap.data)
    kwargs: dict = dict(model=spec.model, n_twists=spec.n_twists, backend=spec.backend)
    robot = get_robot(spec.robot)
    try:
        return RobotPredictor(robot, spec.medium, method=reference, **kwargs), ''
    except (ImportError, AttributeError, ValueError) as exc:
        note = (f'reference method {reference!r} unavailable ({type(exc).__name__}: {exc}); '
                f'compared against {spec.method!r} at n_twists={spec.n_twists} instead '
                '(interpolation error only)')
        return RobotPredictor(robot, spec.medium, method=spec.method, **kwargs), note


def accuracy_report(cmap: CapacityMap, samples: int = 20, seed: int = 0,
                    reference: str = 'direct', progress: bool = False) -> AccuracyReport:
    """Compare `cmap` with a reference method at 2 x `samples` states (see module doc)."""
    predictor, note = reference_predictor(cmap, reference)
    states = sample_states(cmap.grid, samples, seed)
    ph = cmap.phis
    phis = 0.5 * (ph[:-1] + ph[1:])
    comp = MapComparison()
    for s in tqdm(states, unit='state', file=sys.stderr, desc='accuracy', disable=not progress):
        state = AnchorState(*map(float, s))
        for pull in cmap.pulls:
            refs = predictor.predict_many(state, phis, pull)
            for phi, r in zip(phis, refs):
                comp.add(cmap.query(state, float(phi), pull), r)
    return comp.report(predictor.method, len(states), note)


@dataclass(frozen=True)
class CoverageReport:
    """How often a map answers where the live reference does, and how far above it.

    Over `n_states` random (state, pull, phi) of the robot's ranges (accuracy.agreement_states:
    both pulls, phi uniform in -30..10 deg): `ref_answers` states where the reference has a
    value, `map_answers` of those where the map has one too (coverage_pct), `map_only` states
    where only the map has a value (an overestimate of a state that cannot hold), worst and
    p95 of (map - reference) in N where both answer, `map_only_N_worst` the largest map value
    where the reference says `unsupported` (the anchor holds nothing there: 0 N, so the map
    value is its overestimate; NaN when there is none), `over_all_N_worst` the larger of the
    two (the bound a consumer of the map must allow for), and `by_flag` how many map answers
    each rule gave ('' = interior cell).
    """

    robot: str
    reference: str
    n_states: int
    ref_answers: int
    map_answers: int
    coverage_pct: float
    map_only: int
    over_N_worst: float
    err_N_p95: float
    by_flag: dict
    map_only_N_worst: float = float('nan')
    over_all_N_worst: float = float('nan')

    def to_dict(self) -> dict:
        return asdict(self)


def coverage_report(cmap: CapacityMap, n: int = 300, seed: int = 0,
                    reference: str = 'direct', progress: bool = False) -> CoverageReport:
    """The map against the live reference at n random states of its robot (see CoverageReport).
    The reference is the live solver at its defaults (capacity_node's live fallback)."""
    from ..accuracy import agreement_states
    spec = spec_from_map(cmap.data)
    predictor = RobotPredictor(get_robot(spec.robot), spec.medium, model=spec.model,
                               method=reference)
    jobs = agreement_states(spec.robot, n, seed)
    ref_n = ans = only = 0
    over: list[float] = []
    held_nothing: list[float] = []   # map values where the reference holds nothing
    flags: dict[str, int] = {}
    for state, pull, phi in tqdm(jobs, unit='state', file=sys.stderr, desc='coverage',
                                 disable=not progress):
        r = predictor.predict(state, phi, pull)
        m = cmap.query(state, phi, pull)
        if m.capacity_N is not None:
            key = ','.join(m.flags)
            flags[key] = flags.get(key, 0) + 1
        if r.capacity_N is None:
            only += int(m.capacity_N is not None)
            if m.capacity_N is not None and r.status is Status.UNSUPPORTED:
                held_nothing.append(m.capacity_N)
            continue
        ref_n += 1
        if m.capacity_N is not None:
            ans += 1
            over.append(m.capacity_N - r.capacity_N)
    o = np.asarray(over)
    worst = float(o.max()) if o.size else float('nan')
    only_worst = max(held_nothing) if held_nothing else float('nan')
    return CoverageReport(robot=spec.robot, reference=reference, n_states=n, ref_answers=ref_n,
                          map_answers=ans, coverage_pct=100.0 * ans / ref_n if ref_n else
                          float('nan'), map_only=only,
                          over_N_worst=worst,
                          err_N_p95=float(np.percentile(np.abs(o), 95)) if o.size else
                          float('nan'), by_flag=flags, map_only_N_worst=only_worst,
                          over_all_N_worst=float(np.nanmax([worst, only_worst]))
                          if o.size or held_nothing else float('nan'))

