"""Map figures: queries on the shipped prototype map, and the build of the paper grid.

map_query_us: one CapacityMap.query on the shipped prototype map (paper grid) at random
    in-grid states and pull angles; best time per query over repeated batches.
map_build_s: the full prototype paper grid (750 states x 2 pulls x 5 angles, twist-mesh,
    1000 twists) on 2 local worker processes, including pool start-up; one run.
scaling (on request, `--only scaling`): the same build on 1 and on 2 workers, and a map of
    the MiniRQuad description (81 states) on 1 and on 2 workers (best of five, alternating);
    each worker count's time and the speed-up.
"""
from __future__ import annotations

import time
from functools import partial

import numpy as np

from ..maps.grid import prototype_grid
from ..types import AnchorState
from .timing import Figure, best_time, best_times_alternating


def _prototype_map():
    from ..maps.query import CapacityMap
    from ..maps.shipped import SHIPPED, maps_dir
    path = maps_dir() / SHIPPED['prototype']
    if path.exists():
        return CapacityMap.load(path), 'shipped prototype map'
    from ..maps.build import build_map
    return CapacityMap(build_map('prototype', 'glass_beads', workers=2)), 'fresh prototype map'


def map_query_figures(n: int = 200, seed: int = 0) -> list[Figure]:
    cmap, what = _prototype_map()
    g = cmap.grid
    rng = np.random.default_rng(seed)
    lo = np.array([a[0] for a in g.axes])
    hi = np.array([a[-1] for a in g.axes])
    states = [AnchorState(*map(float, x)) for x in lo + (hi - lo) * rng.random((n, 4))]
    phis = (g.phi[0] + (g.phi[-1] - g.phi[0]) * rng.random(n)).tolist()

    def batch():
        for s, p in zip(states, phis):
            cmap.query(s, p, 'backward')

    t = best_time(batch, repeats=7) / n
    return [Figure('map_query_us', 1e6 * t, 'us', budget='<= 20 (paper: 20000)',
                   note=f'{what}, pure-Python 32-corner blend, random in-grid states')]


def map_build_figures(workers: int = 2) -> list[Figure]:
    from ..maps.build import build_map
    grid = prototype_grid()
    t0 = time.perf_counter()
    build_map('prototype', 'glass_beads', grid, workers=workers)
    dt = time.perf_counter() - t0
    return [Figure('map_build_s', dt, 's', budget='<= 60 on 2 cores',
                   note=f'prototype paper grid, {grid.n_states} states x {len(grid.pulls)} '
                        f'pulls x {len(grid.phi)} angles, twist-mesh 1000 twists, '
                        f'{workers} processes incl. start-up')]


def scaling_figures() -> list[Figure]:
    """Map builds on 1 and 2 local workers: the robot map and a described map."""
    from ..description import load_description, shipped_description
    from ..maps.build import build_map
    from ..maps.described import description_grid
    from ..maps.described_build import build_described_map
    from ..rft.media import get_medium
    grid = prototype_grid()
    t = {}
    for w in (1, 2):
        t0 = time.perf_counter()
        build_map('prototype', 'glass_beads', grid, workers=w)
        t[w] = time.perf_counter() - t0
    desc = load_description(shipped_description('minirquad'))
    axes = {'h': [0.030, 0.034, 0.038], 'theta_b': [0.0, 5.0, 10.0],
            'theta_l1': [-50.0, -40.0, -30.0], 'theta_l2': [20.0, 30.0, 40.0]}
    dgrid = description_grid(desc, {k: np.array(v) for k, v in axes.items()}, [-20.0, 0.0],
                             ('backward',))
    # ~1 s each: best of five, one and two workers in turn (a single pair of runs moved the
    # ratio by 0.3 with the load of the moment)
    td = best_times_alternating(
        {w: partial(build_described_map, desc, get_medium('m90_sand'), dgrid,
                    method='twist-mesh', workers=w) for w in (1, 2)}, rounds=5)
    what = f'prototype paper grid ({grid.n_states} states), incl. pool start-up'
    dwhat = (f'MiniRQuad description, {dgrid.n_states} states x 2 angles, incl. pool start-up, '
             'best of 5 alternating')
    return [Figure('map_build_1worker_s', t[1], 's', note=f'{what}, in this process'),
            Figure('map_build_2workers_s', t[2], 's', note=f'{what}, 2 processes'),
            Figure('map_build_2worker_speedup', t[1] / t[2], 'x', budget='>= 1.7',
                   note='1 worker / 2 workers, robot map'),
            Figure('described_build_1worker_s', td[1], 's', note=dwhat),
            Figure('described_build_2workers_s', td[2], 's', note=dwhat),
            Figure('described_build_2worker_speedup', td[1] / td[2], 'x', budget='>= 1.7',
                   note='1 worker / 2 workers, described map')]


def map_figures() -> list[Figure]:
    return map_query_figures() + map_build_figures()
