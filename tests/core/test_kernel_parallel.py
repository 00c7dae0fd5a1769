"""The blocked, parallel, SIMD fused kernel against the numpy reference path.

The numpy path (agarwal._PreparedAgarwal.stress + engine masking) is the independent
reference; the kernel must agree to 1e-12 in float64 for every twist count (blocks of
kernels.BLOCK twists, partial last block, a single twist), for both surface-friction branches,
and give bitwise the same numbers on one thread, two threads, serial or from another thread.
"""
import math
import threading

import numpy as np
import pytest

from rftgls_core.geometry.mesh import Facets
from rftgls_core.geometry.shapes import icosphere
from rftgls_core.rft import kernels
from rftgls_core.rft.agarwal import AgarwalRFT
from rftgls_core.rft.engine import BuriedBody

pytestmark = pytest.mark.skipif(not kernels.AVAILABLE, reason='numba not installed')


def random_facets(rng, n):
    normals = rng.normal(size=(n, 3))
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return Facets(rng.uniform(-0.05, 0.02, (n, 3)), normals, rng.uniform(1e-6, 1e-5, n))


def bodies(facets, mu, **kw):
    model = AgarwalRFT(6.8e5, mu)
    ref = BuriedBody(facets, model, ref=(0.01, 0.0, 0.02), backend='numpy', **kw)
    fused = BuriedBody(facets, model, ref=(0.01, 0.0, 0.02), backend='numba', **kw)
    assert fused.fused and not ref.fused
    return ref, fused


def assert_agree(a, b, tol):
    """numpy sums the facet terms pairwise, the fused kernel in facet order with fused
    multiply-adds: for n terms the two differ by at most (n + 30) eps * sum|term| (each term a
    product of ~30 roundings, the sum n - 1 more), and for these random bodies sum|term| over
    the facets stays within max|W| over all components (measured: ratio 1.0). With n <= 800
    that is <= 2e-13 * max|W|, inside tol = 1e-12 of max|W|."""
    assert np.allclose(a, b, rtol=tol, atol=tol * np.abs(a).max())


@pytest.mark.parametrize('mu', [0.4, math.inf])
@pytest.mark.parametrize('m', [1, kernels.BLOCK - 1, kernels.BLOCK, 3 * kernels.BLOCK + 5])
def test_blocks_agree_with_numpy(mu, m):
    rng = np.random.default_rng(m)
    ref, fused = bodies(random_facets(rng, 400), mu, mirror_y=0.0)
    t6, t3 = rng.normal(size=(m, 6)), rng.normal(size=(m, 3))
    assert_agree(ref.wrench(t6), fused.wrench(t6), 1e-12)
    assert_agree(ref.planar_wrench(t3), fused.planar_wrench(t3), 1e-12)
    assert_agree(ref.planar_wrench(t3, use_symmetry=False),
                 fused.planar_wrench(t3, use_symmetry=False), 1e-12)


@pytest.mark.parametrize('precision', ['float64', 'float32'])
def test_padded_lanes_change_no_twist(precision):
    # A block's twist count is padded to a multiple of kernels.LANES with copies of its first
    # twist: each twist's wrench must be bitwise what it is alone, in a full block or next to
    # any count of others (13: one padded block; BLOCK + 3: a full and a padded one).
    rng = np.random.default_rng(5)
    f = random_facets(rng, 300)
    body = BuriedBody(f, AgarwalRFT(6.8e5, 0.4), ref=(0.01, 0.0, 0.02), mirror_y=0.0,
                      precision=precision)
    for width, call in ((6, body.wrench), (3, body.planar_wrench)):
        t = rng.normal(size=(kernels.BLOCK + 3, width))
        together = call(t)
        alone = np.array([call(row) for row in t])
        assert np.array_equal(together, alone)
        assert np.array_equal(call(t[:13]), together[:13])
        assert np.array_equal(call(t[-3:]), together[-3:])


def test_resting_facets_inside_a_block():
    # Rotation about an axis through facet centroids: those facets rest (no force), the
    # others move; twists of very different sizes share a block (per-twist rest tolerance).
    mesh = icosphere(0.02, 2)
    f = mesh.facets().transformed(np.eye(3), [0.0, 0.0, -0.05])
    ref_pt = f.centroids[7]
    model = AgarwalRFT(6.8e5, 0.4)
    a = BuriedBody(f, model, ref=ref_pt, backend='numpy')
    b = BuriedBody(f, model, ref=ref_pt, backend='numba')
    t = np.zeros((kernels.BLOCK + 3, 6))
    t[:, 3:] = np.random.default_rng(3).normal(size=(len(t), 3))
    t *= np.logspace(-6, 6, len(t))[:, None]
    assert_agree(a.wrench(t), b.wrench(t), 1e-12)


def test_threads_and_serial_give_identical_numbers():
    rng = np.random.default_rng(8)
    _, body = bodies(random_facets(rng, 1500), 0.4)
    t = rng.normal(size=(300, 6))
    assert not kernels.use_parallel(kernels.PARALLEL_MIN_PAIRS - 1)
    k = body._full['fused']
    tw = np.ascontiguousarray(t.T)
    args = (k['r'], k['n'], k['nd'], k['poly'], k['w'], k['mu'], k['c'])
    serial = np.zeros((len(t), 6))
    kernels.spatial_serial(tw, *args, serial)
    before = kernels.threads()
    try:
        for n in sorted({1, kernels.max_threads()}):
            kernels.set_threads(n)
            par = np.zeros_like(serial)
            kernels.spatial_parallel(tw, *args, par)
            assert np.array_equal(par, serial)
            assert np.array_equal(body.wrench(t), serial * k['xi'])
    finally:
        kernels.set_threads(before)
    # From another Python thread the engine takes the serial kernel: same numbers.
    box = {}
    worker = threading.Thread(target=lambda: box.setdefault('w', body.wrench(t)))
    worker.start()
    worker.join(timeout=60)
    assert np.array_equal(box['w'], serial * k['xi'])


def test_float32_costs_little_and_is_opt_in():
    rng = np.random.default_rng(4)
    f = random_facets(rng, 800)
    t = rng.normal(size=(200, 6))
    model = AgarwalRFT(6.8e5, 0.4)
    w64 = BuriedBody(f, model, ref=(0.01, 0.0, 0.02)).wrench(t)
    w32 = BuriedBody(f, model, ref=(0.01, 0.0, 0.02), precision='float32').wrench(t)
    err = np.abs(w32 - w64).max(axis=0) / np.abs(w64).max(axis=0)
    # float32 per pair, float64 sums: about 1e-7 relative; clearly not float64 either.
    assert err.max() < 1e-6 and err.max() > 1e-12
    # Rate independence holds in float32 too, far beyond float32's range of squares.
    b32 = BuriedBody(f, model, ref=(0.01, 0.0, 0.02), precision='float32')
    big = b32.wrench(1e30 * t[:5])
    assert np.all(np.isfinite(big)) and np.allclose(big, w32[:5], rtol=1e-6, atol=0)
    with pytest.raises(ValueError, match='precision'):
        BuriedBody(f, model, precision='float16')
    with pytest.raises(ValueError, match='fused'):
        BuriedBody(f, model, backend='numpy', precision='float32')


def _sphere_facets(depth=0.05):
    mesh = icosphere(0.02, 2)
    return mesh.facets().transformed(np.eye(3), [0.0, 0.0, -depth])


def test_twists_with_and_without_resting_facets_in_one_call():
    # The kernel blocks the twists for which every facet certainly moves apart from the
    # others (kernel_pairs._twist_bounds) and puts each answer back in its row: a call that
    # mixes both kinds gives each twist bitwise its answer alone, and numpy's to 1e-12.
    f = _sphere_facets()
    model = AgarwalRFT(6.8e5, 0.4)
    ref_pt = f.centroids[7]
    a = BuriedBody(f, model, ref=ref_pt, backend='numpy')
    b = BuriedBody(f, model, ref=ref_pt, backend='numba')
    rng = np.random.default_rng(9)
    t = rng.normal(size=(2 * kernels.BLOCK + 7, 6))
    t[::3, :3] = 0.0        # pure rotations about the reference point: facet 7 rests
    together = b.wrench(t)
    assert np.array_equal(together, np.array([b.wrench(row) for row in t]))
    assert_agree(a.wrench(t), together, 1e-12)
    t3 = rng.normal(size=(kernels.BLOCK + 9, 3))
    t3[::4, :2] = 0.0       # planar rotations about the reference point
    together3 = b.planar_wrench(t3)
    assert np.array_equal(together3, np.array([b.planar_wrench(row) for row in t3]))
    assert_agree(a.planar_wrench(t3), together3, 1e-12)


def test_a_facet_between_the_rest_bounds_is_decided_exactly():
    # A facet whose speed lies between the cheap bounds of the rest tolerance (lo, hi) sends
    # its block through the exact tolerance. Here facet 7 moves at 1.0005e-12 of the fastest
    # facet's speed (the numpy path: moving, so it carries its full stress) and below hi:
    # without the exact pass the kernel would drop its force.
    from rftgls_core.rft import kernel_pairs
    f = _sphere_facets()
    model = AgarwalRFT(6.8e5, 0.4)
    c = f.centroids
    axis = (c[0] - c[7]) / np.linalg.norm(c[0] - c[7])  # pure rotation about this axis
    dist = np.linalg.norm(np.cross(c - c[7], axis), axis=1)
    # move the axis sideways so facet 7 sits 1.0005e-12 x the farthest facet's distance away
    side = np.cross(axis, [0.0, 0.0, 1.0])
    side /= np.linalg.norm(side)
    centre = c[7] + 1.0005e-12 * dist.max() * side
    a = BuriedBody(f, model, ref=centre, backend='numpy')
    b = BuriedBody(f, model, ref=centre, backend='numba')
    t = np.zeros((3, 6))
    t[:, 3:] = axis
    t[1, 3:] *= 2.0
    k = b._full['fused']
    tw = np.ascontiguousarray(t.T)
    ext = kernel_pairs._extent(False, k['r'])
    lo, hi, moves = kernel_pairs._twist_bounds(False, tw, 0, k['r'], *ext, k['c'][3], k['c'][4])
    speed = np.linalg.norm(np.cross(t[0, 3:], k['r'][7]))
    assert lo < speed <= hi and not moves
    assert speed > 1e-12 * np.linalg.norm(np.cross(t[0, 3:], k['r']), axis=1).max()
    # Facet 7's velocity is ~4e-14 m/s from lever arms whose rounding is ~1e-17 m: its
    # direction is known to ~1e-4 only, and the two paths round it differently (the kernel
    # contracts into FMA), so its stress differs by up to ~1e-4 of the facet's share of the
    # wrench (1.5e-3 here; measured 2e-8 of the wrench). Dropping the facet (the fast test
    # alone: speed <= hi) changes the wrench by its whole share, 1,000 times the tolerance.
    rest = BuriedBody(f.subset(np.arange(len(c)) != 7), model, ref=centre, backend='numpy')
    w_ref, w_fused, w_without = a.wrench(t), b.wrench(t), rest.wrench(t)
    scale = np.abs(w_ref).max()
    assert np.abs(w_fused - w_ref).max() <= 1e-6 * scale
    assert np.abs(w_without - w_ref).max() >= 1e-3 * scale
