"""Capacity figures: each limit-surface method from scratch on the MiniRQuad DH pose, and the
6D path (one thread where the kernels would otherwise use two)."""
from __future__ import annotations

import math
from functools import partial

from ..posed import PosedAnchorSolver, pose_robot
from ..predictor.live import RobotPredictor
from ..rft.media import get_medium
from ..robots.presets import minirquad
from ..surfaces.registry import METHOD_NAMES
from ..types import Pull
from .engine import TYPICAL_STATE, threads
from .timing import Figure, best_time


def capacity_figures() -> list[Figure]:
    """Per limit-surface method on the MiniRQuad DH pose: from scratch (pose, RFT, fit, one
    query) and the query alone on a fitted surface."""
    robot, medium = minirquad(), get_medium('m90_sand')
    figures = []
    for method in METHOD_NAMES:
        if method == 'brute-force':
            continue   # the dense reference: seconds per state by design, not a live method
        predictor = RobotPredictor(robot, medium, method=method)
        scratch = best_time(partial(predictor.predict, TYPICAL_STATE, 0.0, Pull.BACKWARD),
                            repeats=5)
        surface, _ = predictor.fit(TYPICAL_STATE, Pull.BACKWARD)
        assert surface is not None, f'{method} fails on the typical state'
        query = best_time(partial(surface.capacity, 0.0), repeats=5)
        key = method.replace('-', '_')
        budget = '<= 10' if method == 'direct' else ''
        name = 'capacity_direct_ms' if method == 'direct' else f'capacity_{key}_ms'
        figures.append(Figure(name, 1e3 * scratch, 'ms', budget=budget,
                              note=f'from scratch, {predictor.n_twists} twists'))
        figures.append(Figure(f'fit_{key}_ms', 1e3 * (scratch - query), 'ms',
                              note='pose + RFT + fit'))
        figures.append(Figure(f'query_{key}_us', 1e6 * query, 'us', note='one tether angle'))
    return figures


def capacity_6d_figures() -> list[Figure]:
    """The 6D path from scratch on the MiniRQuad DH pose (posed anchor, RFT of the 6D cloud, support
    check, Newton on S^5): a yawed pull (30 deg), and yaw 0 forced into 6D (there the root sits
    on the switching set of the side faces and is found by the confined Newton)."""
    solver = PosedAnchorSolver(get_medium('m90_sand'), space='6d')

    def scratch(yaw: float) -> None:
        posed = pose_robot(minirquad(), TYPICAL_STATE, Pull.BACKWARD)
        solver.solve(posed, 0.0, math.radians(yaw))

    with threads(1):
        t30 = best_time(partial(scratch, 30.0), repeats=5)
        t0 = best_time(partial(scratch, 0.0), repeats=5)
    return [Figure('capacity_6d_ms', 1e3 * t30, 'ms', budget='<= 50 (one core)',
                   note=f'6D direct from scratch, yaw 30 deg, {solver.n_twists_6d} twists on '
                        'S^5, one core'),
            Figure('capacity_6d_yaw0_ms', 1e3 * t0, 'ms',
                   note='the same at yaw 0 forced into 6D, one core')]
