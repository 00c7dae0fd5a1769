"""Timing helpers for `rftgls bench` (not unit tests: machines are noisy, report ratios).

bench_surfaces() fits every representation to an analytic surface and times fit and query,
plus the worst capacity error against the exact brentq reference.
"""
from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from .alpha_shape import AlphaShapeSurface
from .direct import DirectSurface
from .ellipsoid import EllipsoidSurface
from .synthetic import convex_case, dented_case
from .twist_mesh import TwistMeshSurface


@dataclass(frozen=True)
class BenchRow:
    case: str
    method: str
    n_twists: int
    fit_ms: float            # median over repeats
    query_us: float          # median time per pull angle, capacity_many over the angle sweep
    max_cap_err: float       # worst |relative capacity error| among ok results
    n_ok: int
    n_phi: int

    def as_dict(self) -> dict:
        return asdict(self)


def _median_time(fn, repeats: int) -> float:
    ts = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        ts.append(time.perf_counter() - t0)
    return float(np.median(ts))


def bench_surfaces(n_twists: int = 2000, n_phi: int = 33, repeats: int = 3,
                   cases=('convex', 'dented')) -> list[BenchRow]:
    """Fit and query times per representation on the synthetic cases (seconds to run)."""
    phis = np.linspace(-1.35, 1.35, n_phi)
    makers = {'convex': convex_case, 'dented': dented_case}
    rows = []
    for name in cases:
        case = makers[name]()
        exact = np.array([case.exact_capacity(p) for p in phis])
        for cls, n in ((TwistMeshSurface, n_twists), (EllipsoidSurface, n_twists),
                       (AlphaShapeSurface, n_twists), (DirectSurface, 400)):
            surf = cls(n)
            fit_s = _median_time(lambda: surf.fit(case.problem), repeats)
            q_s = _median_time(lambda: surf.capacity_many(phis), repeats)
            res = surf.capacity_many(phis)
            err = [abs(r.capacity_N - e) / e for r, e in zip(res, exact) if r.ok]
            rows.append(BenchRow(name, cls.method, n, fit_s * 1e3, q_s / n_phi * 1e6,
                                 float(max(err)) if err else float('nan'), len(err), n_phi))
    return rows


def format_rows(rows: list[BenchRow]) -> str:
    head = f'{"case":8} {"method":11} {"N":>5} {"fit ms":>8} {"query us":>9} {"max err":>8} ok'
    lines = [head]
    for r in rows:
        lines.append(f'{r.case:8} {r.method:11} {r.n_twists:5d} {r.fit_ms:8.2f} '
                     f'{r.query_us:9.1f} {r.max_cap_err:8.2e} {r.n_ok}/{r.n_phi}')
    return '\n'.join(lines)
