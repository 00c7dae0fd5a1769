"""Benchmarks behind `rftgls bench`: named figures, measured in one run so they compare as ratios.

Each figure is the best of several repeats (the machines are shared and noisy; the minimum is
the least disturbed estimate). Nothing here is a pass/fail test: the budgets of the
architecture page are printed next to the figures.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from .rft.engine import BuriedBody
from .rft.media import get_medium
from .rft.models import make_model
from .robots.presets import minirquad
from .surfaces.sampling import fibonacci_sphere
from .types import AnchorState, Pull

# A typical buried MiniRQuad pose: the DH anchor of the paper's Table II.
TYPICAL_STATE = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)
GLS_TWISTS = 1000


@dataclass(frozen=True)
class Figure:
    name: str
    value: float
    unit: str
    budget: str = ''
    note: str = ''


def best_time(fn: Callable[[], object], repeats: int = 7, min_total: float = 0.2) -> float:
    """Smallest wall time of one call, s (repeats at least `repeats` times or `min_total` s)."""
    fn()  # warm up: JIT compile, caches
    times, total = [], 0.0
    while len(times) < repeats or total < min_total:
        t0 = time.perf_counter()
        fn()
        dt = time.perf_counter() - t0
        times.append(dt)
        total += dt
        if len(times) > 1000:
            break
    return min(times)


def unit_twists(n: int, char_length: float) -> np.ndarray:
    """n planar twists (vx, vz, wy) uniform on the unit sphere of the scaled metric."""
    ts = fibonacci_sphere(n)
    return np.column_stack([ts[:, 0], ts[:, 1], ts[:, 2] / char_length])


def bench_rft() -> list[Figure]:
    robot = minirquad()
    model = make_model('agarwal', get_medium('m90_sand'))
    twists = unit_twists(GLS_TWISTS, robot.char_length)

    def cloud():
        posed = robot.pose(TYPICAL_STATE, Pull.BACKWARD)
        body = BuriedBody(posed.facets, model, ref=posed.ref, mirror_y=posed.mirror_y)
        return body.planar_wrench(twists)

    posed = robot.pose(TYPICAL_STATE, Pull.BACKWARD)
    figures = []
    for backend in ('numba', 'numpy'):
        try:
            body = BuriedBody(posed.facets, model, ref=posed.ref, backend=backend)
        except ValueError:
            continue
        t = best_time(lambda: body.planar_wrench(twists, use_symmetry=False), repeats=3)
        pairs = body.facets_active * len(twists)
        figures.append(Figure('rft_pairs_per_s' + ('' if backend == 'numba' else '_numpy'),
                              pairs / t, 'pairs/s', note=f'{backend} backend, one core, '
                              f'{body.facets_active} buried facets x {len(twists)} twists'))
    t_cloud = best_time(cloud)
    figures.append(Figure('gls_cloud_ms', 1e3 * t_cloud, 'ms', budget='<= 20 (paper: 800)',
                          note=f'MiniRQuad DH pose, {GLS_TWISTS} twists, pose + cull + mirror + '
                               f'wrenches; {robot.leg_mesh.faces.shape[0]} facets per leg'))
    return figures


def bench_capacity() -> list[Figure]:
    """Per limit-surface method on the MiniRQuad DH pose: from scratch (pose, RFT, fit, one
    query) and the query alone on a fitted surface."""
    from .anchor import AnchorModel
    from .surfaces.registry import METHOD_NAMES

    robot, medium = minirquad(), get_medium('m90_sand')
    figures = []
    for method in METHOD_NAMES:
        model = AnchorModel(robot, medium, method=method)
        scratch = best_time(lambda: model.predict(TYPICAL_STATE, 0.0, Pull.BACKWARD), repeats=5)
        surface, _ = model.fit(TYPICAL_STATE, Pull.BACKWARD)
        query = best_time(lambda: surface.capacity(0.0), repeats=5)
        key = method.replace('-', '_')
        budget = '<= 10' if method == 'direct' else ''
        name = 'capacity_direct_ms' if method == 'direct' else f'capacity_{key}_ms'
        figures.append(Figure(name, 1e3 * scratch, 'ms', budget=budget,
                              note=f'from scratch, {model.n_twists} twists'))
        figures.append(Figure(f'fit_{key}_ms', 1e3 * (scratch - query), 'ms',
                              note='pose + RFT + fit'))
        figures.append(Figure(f'query_{key}_us', 1e6 * query, 'us', note='one tether angle'))
    return figures


# Sections in run order; maps and nodes register theirs where they live.
def bench_maps() -> list[Figure]:
    from .maps.bench import bench_maps as run
    return run()


SECTIONS: dict[str, Callable[[], list[Figure]]] = {'rft': bench_rft, 'capacity': bench_capacity,
                                                  'maps': bench_maps}


def run_all(only: list[str] | None = None, progress: Callable[[str], None] | None = None
            ) -> list[Figure]:
    out: list[Figure] = []
    for name, fn in SECTIONS.items():
        if only and name not in only:
            continue
        if progress:
            progress(name)
        out.extend(fn())
    return out


def format_value(f: Figure) -> str:
    v = f.value
    if not math.isfinite(v):
        return str(v)
    return f'{v:.3g}' if abs(v) < 1e4 else f'{v:.3e}'
