"""Speed against accuracy: every method measured against `direct` over a spread of states.

A *configuration* is (method, twist count, leg mesh resolution); 'map' is the shipped map of
the robot (its states are drawn inside the map's grid). For each state (random but
seeded, inside the robot's map ranges), both pull orientations and a few tether angles, it
records the capacity, slip twist, status and the time to answer from scratch (pose, RFT,
fit, query). Errors are taken against `direct` on the finest leg mesh (the reference), and,
for the acceptance numbers of each method, against `direct` on the same mesh.
"""
from __future__ import annotations

import math
import time
from collections import Counter
from dataclasses import asdict, dataclass, field

import numpy as np

from .predictor.live import RobotPredictor
from .predictor.protocol import Predictor
from .rft.media import get_medium
from .robots.presets import LEG_ARC_SEGMENTS, get_robot
from .surfaces.brute_force import BruteForceSurface
from .types import AnchorState, Pull

# Ranges the states are drawn from (SI): the prototype's paper grid and a box around the
# MiniRQuad anchors of Table II.
STATE_RANGES = {
    'prototype': {'h': (0.005, 0.030), 'theta_b': (-20, 20), 'theta_l1': (-40, 40),
                  'theta_l2': (-40, 40)},
    'minirquad': {'h': (0.025, 0.055), 'theta_b': (-5, 15), 'theta_l1': (-60, 0),
                  'theta_l2': (-20, 40)},
}
MEDIUM = {'prototype': 'glass_beads', 'minirquad': 'm90_sand'}
PHIS_DEG = (0.0, -20.0)
REFERENCE_ARC = 48


@dataclass(frozen=True)
class Config:
    method: str
    n_twists: int
    n_arc: int = LEG_ARC_SEGMENTS
    polish: bool = True     # twist-mesh only: Newton polish of the facet hit

    @property
    def label(self) -> str:
        if self.method == 'map':
            return 'map (shipped grid) N=1000 arc=24'
        raw = '' if self.polish or self.method != 'twist-mesh' else ' mesh-only'
        return f'{self.method}{raw} N={self.n_twists} arc={self.n_arc}'

    @property
    def options(self) -> dict:
        return {'polish': self.polish} if self.method == 'twist-mesh' else {}


DEFAULT_CONFIGS = (
    [Config('twist-mesh', n) for n in (100, 250, 500, 1000, 2000)]
    + [Config('twist-mesh', n, polish=False) for n in (500, 1000, 2000, 4000)]
    + [Config('twist-mesh', 1000, a) for a in (8, 12, 16)]
    + [Config('direct', 1000, a) for a in (8, 12, 16, LEG_ARC_SEGMENTS)]
    + [Config('direct', 400)]     # the default bracketing sphere of direct
    + [Config('ellipsoid', n) for n in (500, 2000)]
    + [Config('alpha', n) for n in (1000, 2000)]
    + [Config('map', 1000)]     # the shipped maps (twist-mesh, 1000 twists, 24 arc segments)
    + [Config('brute-force', 100_000)]   # the dense closure reference (independent, slow)
)


def sample_states(robot: str, n: int, seed: int = 0) -> list[AnchorState]:
    rng = np.random.default_rng(seed)
    r = STATE_RANGES[robot]
    out = []
    for _ in range(n):
        out.append(AnchorState(rng.uniform(*r['h']),
                               *(math.radians(rng.uniform(*r[k]))
                                 for k in ('theta_b', 'theta_l1', 'theta_l2'))))
    return out


@dataclass(frozen=True)
class Record:
    robot: str
    config: str
    method: str
    n_twists: int
    n_arc: int
    state: tuple
    pull: str
    phi_deg: float
    status: str
    capacity_N: float | None
    twist: tuple | None
    seconds: float          # pose + RFT + fit + one query, from scratch
    reason: str = ''
    flags: tuple[str, ...] = ()


def run_config(robot: str, config: Config, states, phis_deg=PHIS_DEG) -> list[Record]:
    predictor: Predictor
    if config.method == 'map':
        from .predictor import PredictorSpec, build_predictor
        predictor = build_predictor(PredictorSpec(map=robot, robot=robot))   # the shipped map
    else:
        predictor = RobotPredictor(get_robot(robot, config.n_arc), get_medium(MEDIUM[robot]),
                                   method=config.method, n_twists=config.n_twists,
                                   surface_options=config.options)
    predictor.predict(states[0], 0.0, Pull.BACKWARD)  # warm caches (JIT, twist sphere)
    out = []
    for state in states:
        for pull in Pull:
            for phi in phis_deg:
                t0 = time.perf_counter()
                res = predictor.predict(state, math.radians(phi), pull)
                dt = time.perf_counter() - t0
                out.append(Record(robot, config.label, config.method, config.n_twists,
                                  config.n_arc, state.as_tuple(), pull.value, phi,
                                  res.status.value, res.capacity_N, res.slip_twist_scaled, dt,
                                  res.reason, tuple(res.flags)))
    return out


def twist_angle_deg(a, b) -> float:
    c = float(np.clip(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)), -1.0, 1.0))
    return math.degrees(math.acos(c))


@dataclass(frozen=True)
class Summary:
    config: str
    method: str
    n_twists: int
    n_arc: int
    time_ms_median: float
    compared: int            # queries where both sides carry a value
    status_mismatch: int     # queries where only one side carries a value
    cap_err_pct_mean: float
    cap_err_pct_p95: float
    cap_err_pct_worst: float
    cap_err_N_worst: float
    cap_over_pct_worst: float    # largest overestimate (positive = above the reference)
    twist_err_deg_mean: float
    twist_err_deg_p95: float
    twist_err_deg_worst: float
    # Coverage: every query is counted, also those where the reference has no value.
    queries: int = 0
    answered_pct: float = math.nan           # queries this configuration answers with a value
    answered_where_ref_pct: float = math.nan  # ... of those the reference answers
    status_agree_pct: float = math.nan       # value / no value the same as the reference
    ref_no_value: int = 0                    # queries the reference does not answer
    outcomes: dict = field(default_factory=dict)   # 'status' or 'status:reason' -> count

    def to_dict(self) -> dict:
        return asdict(self)


def summarise(records: list[Record], reference: list[Record]) -> Summary:
    """Errors of `records` against `reference` (same states, pulls and angles, same order)."""
    cap_pct, cap_n, over, tw = [], [], [], []
    mismatch = 0
    for r, ref in zip(records, reference, strict=True):
        assert (r.state, r.pull, r.phi_deg) == (ref.state, ref.pull, ref.phi_deg)
        if (r.capacity_N is None) != (ref.capacity_N is None):
            mismatch += 1
            continue
        if r.capacity_N is None or ref.capacity_N is None:
            continue
        diff = r.capacity_N - ref.capacity_N
        scale = max(ref.capacity_N, 1e-9)
        cap_pct.append(100 * abs(diff) / scale)
        over.append(100 * diff / scale)
        cap_n.append(abs(diff))
        tw.append(twist_angle_deg(r.twist, ref.twist))
    stat = lambda a, f: float(f(a)) if a else math.nan
    times = [r.seconds for r in records]
    r0 = records[0]
    n = len(records)
    answered = sum(r.capacity_N is not None for r in records)
    ref_answers = [r for r, ref in zip(records, reference) if ref.capacity_N is not None]
    where_ref = sum(r.capacity_N is not None for r in ref_answers)
    outcomes = Counter(r.status + (f':{r.reason}' if r.reason else '') for r in records)
    return Summary(r0.config, r0.method, r0.n_twists, r0.n_arc,
                   1e3 * float(np.median(times)), len(cap_pct), mismatch,
                   stat(cap_pct, np.mean), stat(cap_pct, lambda a: np.percentile(a, 95)),
                   stat(cap_pct, np.max), stat(cap_n, np.max), stat(over, np.max),
                   stat(tw, np.mean), stat(tw, lambda a: np.percentile(a, 95)), stat(tw, np.max),
                   queries=n, answered_pct=100.0 * answered / n,
                   answered_where_ref_pct=(100.0 * where_ref / len(ref_answers)
                                           if ref_answers else math.nan),
                   status_agree_pct=100.0 * (n - mismatch) / n,
                   ref_no_value=n - len(ref_answers), outcomes=dict(sorted(outcomes.items())))


def pareto_front(points: list[tuple[float, float]]) -> list[int]:
    """Indices of points no other point beats in both time and error (lower is better)."""
    order = sorted(range(len(points)), key=lambda i: (points[i][0], points[i][1]))
    front, best = [], math.inf
    for i in order:
        if points[i][1] < best:
            front.append(i)
            best = points[i][1]
    return front


# -- agreement with the brute-force reference --------------------------------------------------

AGREEMENT_METHODS = ('direct', 'twist-mesh')


def agreement_states(robot: str, n: int, seed: int = 0
                     ) -> list[tuple[AnchorState, Pull, float]]:
    """n random (state, pull, phi) inside the robot's ranges; both pulls; phi in -30..10 deg."""
    rng = np.random.default_rng(seed)
    states = sample_states(robot, n, seed)
    return [(s, Pull.FORWARD if k % 2 else Pull.BACKWARD, math.radians(rng.uniform(-30, 10)))
            for k, s in enumerate(states)]


def agreement(robot: str, n_states: int, seed: int = 0, reference_twists: int = 100_000,
              progress=None) -> dict:
    """direct and twist-mesh (defaults) against the brute-force closure reference.

    Relative capacity errors are taken against max(reference, 5 % of the robot's weight), so
    that capacities close to zero do not dominate. The reference is refined locally around
    its exit (surfaces/brute_force.py) and reports its own error bound per state
    (`error_N` in each row, the worst in `reference_err_N_worst` and, relative like the
    methods' errors, `reference_err_pct_worst`): an overestimate is only meaningful where it
    exceeds that bound.
    """
    rob = get_robot(robot)
    medium = get_medium(MEDIUM[robot])
    predictors = {m: RobotPredictor(rob, medium, method=m) for m in AGREEMENT_METHODS}
    reference = RobotPredictor(rob, medium, method='brute-force', n_twists=reference_twists)
    floor = 0.05 * rob.mass * 9.81
    rows = []
    jobs = agreement_states(robot, n_states, seed)
    for state, pull, phi in (progress(jobs) if progress else jobs):
        ref_surface, failure = reference.fit(state, pull)
        ref = failure if ref_surface is None else ref_surface.capacity(phi)
        assert ref is not None
        ref_err = (ref_surface.errors_N_[0] if isinstance(ref_surface, BruteForceSurface)
                   and ref.capacity_N is not None and ref_surface.errors_N_ else None)
        row = {'state': state.as_tuple(), 'pull': pull.value, 'phi_deg': math.degrees(phi),
               'brute-force': {'status': ref.status.value, 'capacity_N': ref.capacity_N,
                               'error_N': ref_err}}
        for m, predictor in predictors.items():
            t0 = time.perf_counter()
            r = predictor.predict(state, phi, pull)
            row[m] = {'status': r.status.value, 'reason': r.reason, 'capacity_N': r.capacity_N,
                      'flags': list(r.flags), 'ms': 1e3 * (time.perf_counter() - t0)}
        rows.append(row)
    summary = {}
    for m in AGREEMENT_METHODS:
        same = [r[m]['status'] == r['brute-force']['status'] for r in rows]
        err = [(r[m]['capacity_N'] - r['brute-force']['capacity_N'])
               / max(r['brute-force']['capacity_N'], floor)
               for r in rows if r[m]['capacity_N'] is not None
               and r['brute-force']['capacity_N'] is not None]
        summary[m] = {
            'status_agree_pct': 100.0 * float(np.mean(same)),
            'degenerate_pct': 100.0 * float(np.mean([r[m]['status'] == 'degenerate'
                                                    for r in rows])),
            'compared': len(err),
            'cap_err_pct_p95': 100.0 * float(np.percentile(np.abs(err), 95)) if err else None,
            'cap_over_pct_worst': 100.0 * float(np.max(err)) if err else None,
            'time_ms_median': float(np.median([r[m]['ms'] for r in rows])),
        }
    ref_errs = [r['brute-force']['error_N'] for r in rows
                if r['brute-force']['capacity_N'] is not None]
    known = [e for e in ref_errs if e is not None]
    ref_err_worst = max(known) if known and len(known) == len(ref_errs) else None
    ref_err_pct = (100.0 * max(r['brute-force']['error_N']
                               / max(r['brute-force']['capacity_N'], floor)
                               for r in rows if r['brute-force']['capacity_N'] is not None)
                   if ref_err_worst is not None else None)
    all_three = [r for r in rows if len({r[m]['status'] for m in AGREEMENT_METHODS}
                                        | {r['brute-force']['status']}) == 1]
    return {'robot': robot, 'states': n_states, 'seed': seed,
            'reference': f'brute-force N={reference_twists}',
            'error_floor_N': floor, 'reference_err_N_worst': ref_err_worst,
            'reference_err_pct_worst': ref_err_pct,
            'all_agree_pct': 100.0 * len(all_three) / len(rows),
            'summary': summary, 'rows': rows}
