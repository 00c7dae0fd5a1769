"""Burrow-plan figures (planning/): a full plan from the gait map, as onboard.

plan_onboard_ms: `plan_from_map` on the loaded gait map (every gait's answer from its stored
    runs at phi 0 and -20 deg, the front, the chosen gait for 1.96 N at 95 %): the work a node
    does per decision once the map is loaded. Best of repeated runs.
plan_map_load_ms: reading and verifying the gait map (content hash), done once at start-up.
The shipped gait map when there is one; else a map of the first gaits of the grid built here
(one worker, a few seconds per gait), said in the note.
"""
from __future__ import annotations

import math
import time

from .timing import Figure, best_time

PHIS = (0.0, math.radians(-20.0))
NEED_N = 1.96


def _gait_map():
    from ..planning.gait_map import load, shipped_paths
    paths = shipped_paths('minirquad')
    if paths:
        path = paths[0]
        t0 = time.perf_counter()
        gmap = load(path)
        return gmap, time.perf_counter() - t0, f'shipped {path.name}'
    from ..planning.gait_map import build_gait_map
    from ..planning.gaits import table_ii_gaits
    from ..planning.predict import PlanInputs
    from ..planning.spread import Spread
    from ..rft.media import get_medium, medium_covariance
    m = get_medium('m90_sand')
    cov, src = medium_covariance(None, m.xi_n)
    inputs = PlanInputs('minirquad', m, Spread.of(cov, src), PHIS,
                        sled_kg=0.4)
    gmap = build_gait_map(inputs, [g for g in table_ii_gaits() if g.name == 'SH'], workers=1)
    return gmap, math.nan, 'no shipped gait map: SH alone, built here'


def plan_figures() -> list[Figure]:
    from ..planning.planner import plan_from_map
    gmap, t_load, what = _gait_map()
    phis = [p for p in PHIS if abs(gmap.phis - p).min() < 1e-9]
    n = len(gmap.arrays['gaits'])
    t = best_time(lambda: plan_from_map(gmap, phis, NEED_N, 0.95))
    return [Figure('plan_onboard_ms', 1e3 * t, 'ms', budget='<= 50',
                   note=f'{what}: {n} gaits x {len(gmap.arrays["run_labels"])} runs, '
                        f'{len(phis)} tether angles, need {NEED_N} N at 95 %'),
            Figure('plan_map_load_ms', 1e3 * t_load, 'ms',
                   note='read and verify the gait map (once, at start-up)')]
