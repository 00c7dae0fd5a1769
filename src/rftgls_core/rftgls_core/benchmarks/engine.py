"""RFT engine figures: the fused kernels against this run's peak and against the numpy path.

Workloads:
- planar: the MiniRQuad DH pose of the paper's Table II, 1,000 unit planar twists, the whole
  buried body (`rft_pairs_per_s`), and the GLS point cloud from scratch (`gls_cloud_ms`);
- 6D: a 5,120-facet icosphere (4 subdivisions) of 5 cm radius, centre 10 cm deep (every facet
  buried), 1,000 random spatial twists about its centre (`rft_sphere5120_1000_ms`); the
  throughput figures (`rft_pairs_per_s_1core`, `_2core`) time calls of the first 128.

Each pairs/s figure carries the kernel's flops per pair (rft/kernels.py, FLOPS_PER_PAIR), so
the registry reports it as a share of the measured peak, and the numpy path's figure on the
same work, so it reports the ratio. One and two threads are timed alternately.
"""
from __future__ import annotations

from functools import partial

import numpy as np

from ..geometry.shapes import icosphere
from ..rft import kernels
from ..rft.engine import BuriedBody
from ..rft.media import get_medium
from ..rft.models import make_model
from ..robots.presets import minirquad
from ..surfaces.sampling import fibonacci_sphere
from ..types import AnchorState, Pull
from .timing import Figure, best_time, best_times_alternating

# A typical buried MiniRQuad pose: the DH anchor of the paper's Table II.
TYPICAL_STATE = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)
GLS_TWISTS = 1000
SPHERE_SUBDIVISIONS = 4
SPHERE_RADIUS_M = 0.05
SPHERE_DEPTH_M = 0.10
SPHERE_TWISTS = 1000
# Twists per timed call of the 6D throughput figures (two blocks of 64: one per thread).
SHORT_TWISTS = 128


def unit_twists(n: int, char_length: float) -> np.ndarray:
    """n planar twists (vx, vz, wy) uniform on the unit sphere of the scaled metric."""
    ts = fibonacci_sphere(n)
    return np.column_stack([ts[:, 0], ts[:, 1], ts[:, 2] / char_length])


def sphere_workload(precision: str = 'float64', backend: str = 'auto'
                    ) -> tuple[BuriedBody, np.ndarray]:
    """The generic 6D workload: the buried icosphere (Agarwal, M90 sand) and its twists."""
    mesh = icosphere(SPHERE_RADIUS_M, SPHERE_SUBDIVISIONS)
    centre = np.array([0.0, 0.0, -SPHERE_DEPTH_M])
    facets = mesh.facets().transformed(np.eye(3), centre)
    body = BuriedBody(facets, make_model('agarwal', get_medium('m90_sand')), ref=centre,
                      precision=precision, backend=backend)
    rng = np.random.default_rng(16)
    # Angular rates scaled by 1/radius so rotation and translation move facets alike.
    scale = np.r_[np.ones(3), np.full(3, 1.0 / SPHERE_RADIUS_M)]
    twists = rng.normal(size=(SPHERE_TWISTS, 6)) * scale
    return body, twists


class threads:
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


def planar_figures() -> list[Figure]:
    """The planar kernel and the numpy path on the DH pose, one thread; the GLS cloud."""
    robot = minirquad()
    model = make_model('agarwal', get_medium('m90_sand'))
    twists = unit_twists(GLS_TWISTS, robot.char_length)
    posed = robot.pose(TYPICAL_STATE, Pull.BACKWARD)
    bodies = {b: BuriedBody(posed.facets, model, ref=posed.ref, backend=b)
              for b in ('auto', 'numpy')}
    pairs = bodies['numpy'].facets_active * len(twists)
    what = f"{bodies['numpy'].facets_active} buried facets x {len(twists)} twists, one thread"
    figures = []
    with threads(1):
        # the kernel's call takes ~1.5 ms, the numpy path's ~100: many of the first (a short
        # call often runs undisturbed on a busy machine), a few of the second
        t = {b: best_time(partial(body.planar_wrench, twists, use_symmetry=False),
                          repeats=101 if b == 'auto' else 3, min_total=0.0)
             for b, body in bodies.items()}
    if bodies['auto'].fused:
        figures.append(Figure('rft_pairs_per_s', pairs / t['auto'], 'pairs/s',
                              note=f'fused planar kernel, MiniRQuad DH pose, {what}',
                              flops=kernels.FLOPS_PER_PAIR['planar'],
                              numpy_ref='rft_pairs_per_s_numpy'))
    figures.append(Figure('rft_pairs_per_s_numpy', pairs / t['numpy'], 'pairs/s',
                          note=f'numpy reference path, same work ({what})'))

    def cloud():
        p = robot.pose(TYPICAL_STATE, Pull.BACKWARD)
        body = BuriedBody(p.facets, model, ref=p.ref, mirror_y=p.mirror_y)
        return body.planar_wrench(twists)

    figures.append(Figure('gls_cloud_ms', 1e3 * best_time(cloud), 'ms',
                          budget='<= 20 (paper: 800)',
                          note=f'MiniRQuad DH pose, {GLS_TWISTS} twists: pose + cull + mirror '
                               f'+ wrenches; {robot.leg_mesh.faces.shape[0]} facets per leg'))
    return figures


def spatial_figures() -> list[Figure]:
    """The 6D kernel on one and two threads, float32, and the numpy path, on the sphere.

    Throughput is timed on calls of SHORT_TWISTS twists (two blocks, ~3 ms on one
    thread), best of many, alternating one and two threads: on a shared machine a call that
    short often runs undisturbed, a 1,000-twist call (25 ms) rarely does at load 10. The
    1,000-twist call is timed too, as a figure of its own."""
    body, twists = sphere_workload()
    short = twists[:SHORT_TWISTS]
    what = f'{body.facets_active}-facet sphere x random 6D twists, Agarwal'
    figures = []
    if body.fused:
        flops = kernels.FLOPS_PER_PAIR['spatial']
        counts = sorted({1, min(2, kernels.max_threads())})
        fns = {}
        for n in counts:
            def run(n=n):
                with threads(n):
                    body.wrench(short)
            fns[n] = run
        t = best_times_alternating(fns, rounds=101)
        pairs = body.facets_active * len(short)
        calls = f"calls of {len(short)} twists, best of 101 alternating"
        figures.append(Figure('rft_pairs_per_s_1core', pairs / t[1], 'pairs/s',
                              note=f'{what}, one thread, {calls}', flops=flops,
                              numpy_ref='rft_pairs_per_s_6d_numpy'))
        if 2 in t:
            with threads(2):
                t_all = best_time(partial(body.wrench, twists), repeats=7)
            figures += [
                Figure('rft_pairs_per_s_2core', pairs / t[2], 'pairs/s', budget='>= 1e8',
                       note=f'{what}, two threads, {calls}', flops=flops, threads=2,
                       numpy_ref='rft_pairs_per_s_6d_numpy'),
                Figure('rft_2core_speedup', t[1] / t[2], 'x', budget='>= 1.8 (quiet machine)',
                       note='two threads / one thread, timed alternately'),
                Figure('rft_sphere5120_1000_ms', 1e3 * t_all, 'ms', budget='<= 55',
                       note=f'{what}: all {len(twists)} twists in one call, two threads')]
        b32, _ = sphere_workload('float32')
        w64, w32 = body.wrench(twists), b32.wrench(twists)
        with threads(1):
            t32 = best_time(partial(b32.wrench, short), repeats=21)
        err = float(np.max(np.abs(w32 - w64) / np.abs(w64).max(axis=0)))
        figures += [
            Figure('rft_pairs_per_s_float32_1core', pairs / t32, 'pairs/s',
                   note=f'{what}, float32 per pair (sums in float64), one thread, {calls}',
                   numpy_ref='rft_pairs_per_s_6d_numpy'),
            Figure('rft_float32_rel_error', err, '', note='largest float32 - float64 '
                   'difference over the 1,000 wrenches, per component, relative to that '
                   "component's largest magnitude")]
    ref, _ = sphere_workload(backend='numpy')
    t_np = best_time(partial(ref.wrench, short), repeats=5, min_total=0.0)
    figures.append(Figure('rft_pairs_per_s_6d_numpy', body.facets_active * len(short) / t_np,
                          'pairs/s', note=f'numpy reference path, same work ({what}, calls '
                                          f'of {len(short)} twists)'))
    return figures


def engine_figures() -> list[Figure]:
    return planar_figures() + spatial_figures()
