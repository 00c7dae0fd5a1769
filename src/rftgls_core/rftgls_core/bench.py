"""Benchmarks behind `rftgls bench`: named figures, measured in one run so they compare as ratios.

Each figure is the best of several repeats (the machines are shared and noisy; the minimum is
the least disturbed estimate, see timing.py). Nothing here is a pass/fail test: the budgets of
the architecture page are printed next to the figures.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable
from functools import partial

import numpy as np

from .geometry.shapes import icosphere
from .maps.bench import bench_maps
from .rft import kernels
from .rft.engine import BuriedBody
from .rft.media import get_medium
from .rft.models import make_model
from .robots.presets import minirquad
from .surfaces.sampling import fibonacci_sphere
from .timing import Figure, best_time
from .types import AnchorState, Pull

# A typical buried MiniRQuad pose: the DH anchor of the paper's Table II.
TYPICAL_STATE = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)
GLS_TWISTS = 1000
# The generic 6D workload: a 5,120-facet icosphere (4 subdivisions) of 5 cm radius, centre
# 10 cm deep (all facets buried), 1,000 random spatial twists about its centre.
SPHERE_SUBDIVISIONS = 4
SPHERE_RADIUS_M = 0.05
SPHERE_DEPTH_M = 0.10
SPHERE_TWISTS = 1000


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
        with _threads(1):
            t = best_time(partial(body.planar_wrench, twists, use_symmetry=False), repeats=3)
        pairs = body.facets_active * len(twists)
        figures.append(Figure('rft_pairs_per_s' + ('' if backend == 'numba' else '_numpy'),
                              pairs / t, 'pairs/s', note=f'{backend} backend, one core, '
                              f'{body.facets_active} buried facets x {len(twists)} twists'))
    t_cloud = best_time(cloud)
    figures.append(Figure('gls_cloud_ms', 1e3 * t_cloud, 'ms', budget='<= 20 (paper: 800)',
                          note=f'MiniRQuad DH pose, {GLS_TWISTS} twists, pose + cull + mirror + '
                               f'wrenches; {robot.leg_mesh.faces.shape[0]} facets per leg'))
    return figures


def sphere_workload(precision: str = 'float64') -> tuple[BuriedBody, np.ndarray]:
    """The generic 6D workload: the buried icosphere (Agarwal, M90 sand) and its twists."""
    mesh = icosphere(SPHERE_RADIUS_M, SPHERE_SUBDIVISIONS)
    centre = np.array([0.0, 0.0, -SPHERE_DEPTH_M])
    facets = mesh.facets().transformed(np.eye(3), centre)
    body = BuriedBody(facets, make_model('agarwal', get_medium('m90_sand')), ref=centre,
                      precision=precision)
    rng = np.random.default_rng(16)
    # Angular rates scaled by 1/radius so rotation and translation move facets alike.
    scale = np.r_[np.ones(3), np.full(3, 1.0 / SPHERE_RADIUS_M)]
    twists = rng.normal(size=(SPHERE_TWISTS, 6)) * scale
    return body, twists


def bench_rft_6d() -> list[Figure]:
    """The fused kernel on the generic 6D workload on one core, two cores and all cores."""
    body, twists = sphere_workload()
    if not body.fused:
        return []
    pairs = body.facets_active * len(twists)
    what = f'{body.facets_active}-facet sphere x {len(twists)} random 6D twists, Agarwal'
    cores = kernels.max_threads()
    times = {}
    for n in sorted({1, min(2, cores), cores}):
        with _threads(n):
            times[n] = best_time(lambda: body.wrench(twists), repeats=5)
    two = times[2] if 2 in times else math.nan
    return [
        Figure('rft_pairs_per_s_1core', pairs / times[1], 'pairs/s', note=f'{what}, one thread'),
        Figure('rft_pairs_per_s_2core', pairs / two, 'pairs/s', budget='>= 1e8 and >= 1.7x 1core',
               note=f'{what}, two threads'),
        Figure('rft_sphere5120_1000_ms', 1e3 * times[cores], 'ms', budget='<= 55',
               note=f'{what}, all {cores} threads'),
    ]


class _threads:
    """Run the kernels on n threads inside the block (restores the previous count)."""

    def __init__(self, n: int):
        self.n = n

    def __enter__(self):
        self.before = kernels.threads()
        if kernels.AVAILABLE:
            kernels.set_threads(self.n)

    def __exit__(self, *exc):
        if kernels.AVAILABLE:
            kernels.set_threads(self.before)


def bench_capacity() -> list[Figure]:
    """Per limit-surface method on the MiniRQuad DH pose: from scratch (pose, RFT, fit, one
    query) and the query alone on a fitted surface."""
    from .predictor.live import RobotPredictor
    from .surfaces.registry import METHOD_NAMES

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


def bench_capacity_6d() -> list[Figure]:
    """The 6D path from scratch on the MiniRQuad DH pose (posed anchor, RFT of the 6D cloud, support
    check, Newton on S^5): a yawed pull (30 deg), and yaw 0 forced into 6D (there the root sits
    on the switching set of the side faces and is found by the confined Newton)."""
    import math

    from .posed import PosedAnchorSolver, pose_robot

    solver = PosedAnchorSolver(get_medium('m90_sand'), space='6d')

    def scratch(yaw: float) -> None:
        posed = pose_robot(minirquad(), TYPICAL_STATE, Pull.BACKWARD)
        solver.solve(posed, 0.0, math.radians(yaw))

    with _threads(1):
        t30 = best_time(partial(scratch, 30.0), repeats=5)
        t0 = best_time(partial(scratch, 0.0), repeats=5)
    return [Figure('capacity_6d_ms', 1e3 * t30, 'ms', budget='<= 50 (one core)',
                   note=f'6D direct from scratch, yaw 30 deg, {solver.n_twists_6d} twists on '
                        'S^5, one core'),
            Figure('capacity_6d_yaw0_ms', 1e3 * t0, 'ms',
                   note='the same at yaw 0 forced into 6D, one core')]


# The live stream: a MiniRQuad message stream at the DH pose, 1,000 states, burrowing slowly
# (p 1 mm deeper, proximal legs 2 deg further in over the stream: 2 s at 500 Hz) under sensor
# noise (h 0.05 mm, angles 0.06 deg, one sigma), pulled at phi = -20 deg.
LIVE_STATES = 1000
LIVE_PHI = math.radians(-20.0)
LIVE_DRIFT = (-0.001, 0.0, math.radians(-2.0), 0.0)
LIVE_SIGMA = (5e-5, math.radians(0.06), math.radians(0.06), math.radians(0.06))


def live_stream(n: int = LIVE_STATES, seed: int = 16) -> list[AnchorState]:
    """The states of the live benchmark (see LIVE_DRIFT, LIVE_SIGMA), SI."""
    rng = np.random.default_rng(seed)
    base = np.array(TYPICAL_STATE.as_tuple())
    drift, sigma = np.array(LIVE_DRIFT), np.array(LIVE_SIGMA)
    return [AnchorState(*(base + drift * k / n + rng.normal(0.0, sigma))) for k in range(n)]


def bench_live() -> list[Figure]:
    """Warm-started direct over the live stream, every state timed (median and p99 of the
    calls, not best-of), against the cold direct on a sample of the same states."""
    from .predictor.live import RobotPredictor

    robot, medium = minirquad(), get_medium('m90_sand')
    states = live_stream()
    warm = RobotPredictor(robot, medium, method='direct-warm')
    cold = RobotPredictor(robot, medium, method='direct')
    warm.predict(states[0], LIVE_PHI, Pull.BACKWARD)   # compile and cache, then start afresh
    warm = RobotPredictor(robot, medium, method='direct-warm')
    times, cpu = [], []
    for st in states:
        c0, t0 = time.thread_time(), time.perf_counter()
        warm.predict(st, LIVE_PHI, Pull.BACKWARD)
        times.append(time.perf_counter() - t0)
        cpu.append(time.thread_time() - c0)
    t_cold = []
    for st in states[::20]:
        t0 = time.perf_counter()
        cold.predict(st, LIVE_PHI, Pull.BACKWARD)
        t_cold.append(time.perf_counter() - t0)
    us = np.sort(np.asarray(times)) * 1e6
    solver = warm.solver(Pull.BACKWARD)
    what = f'{len(states)} MiniRQuad states near DH, noise and slow burrowing'
    return [
        Figure('capacity_live_warm_us_median', float(np.median(us)), 'us', budget='<= 1000',
               note=f'warm-started direct per message, {what}'),
        Figure('capacity_live_warm_us_p99', float(np.percentile(us, 99)), 'us',
               budget='<= 5000', note='same stream'),
        Figure('capacity_live_fallback_rate', solver.fallback_rate_, '',
               note=f'cold solves / messages (the first is cold); '
                    f'{dict(solver.fallback_reasons_)}'),
        Figure('capacity_live_cold_us_median', 1e6 * float(np.median(t_cold)), 'us',
               note=f'cold direct on every 20th state of the same stream ({len(t_cold)})'),
        # CPU time of the calling thread: what the call costs without the waits a shared
        # machine adds to the wall time (the warm steps run the kernel on this thread only).
        Figure('capacity_live_warm_cpu_us_median', 1e6 * float(np.median(cpu)), 'us',
               note='same calls, thread CPU time'),
        Figure('capacity_live_warm_cpu_us_p99', 1e6 * float(np.percentile(cpu, 99)), 'us',
               note='same calls, thread CPU time'),
    ]


# Sections in run order.
SECTIONS: dict[str, Callable[[], list[Figure]]] = {'rft': lambda: bench_rft() + bench_rft_6d(),
                                                  'capacity': lambda: (bench_capacity()
                                                                       + bench_capacity_6d()),
                                                  'live': bench_live,
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
