"""Agarwal 3D-RFT stress: reference values from docs/design/models-rft.md 4.8 (derived there from
the public coefficient table), the frame-free/optimised forms against each other, and the
fused numba kernel against numpy."""
import math

import numpy as np
import pytest

from rftgls_core.rft import kernels
from rftgls_core.rft.agarwal import AgarwalRFT, downward_normal, generic_stress

S = math.sqrt(0.5)
# (outward n, v_hat) -> alpha_gen and alpha capped at mu_surf = 0.4; xi_n = 1
# (docs/design/models-rft.md 4.8)
TABLE_4_8 = [
    ((0, 0, -1), (0, 0, -1), (0, 0, 0.875), (0, 0, 0.875)),
    ((0, 0, 1), (0, 0, 1), (0, 0, -0.080), (0, 0, -0.080)),
    ((0, 0, -1), (1, 0, 0), (-0.042, 0, 0.110), (-0.042, 0, 0.110)),
    ((1, 0, 0), (1, 0, 0), (-0.229, 0, 0.089), (-0.229, 0, 0.089)),   # public-code tie-break
    ((S, 0, -S), (1, 0, 0), (-0.391, 0, 0.280), (-0.391, 0, 0.280)),
    ((S, 0, S), (1, 0, 0), (-0.155, 0, -0.089), (-0.155, 0, -0.089)),
    ((S, 0, -S), (0, 0, -1), (-0.193, 0, 0.855), (-0.314, 0, 0.734)),
]


def prepared_stress(model, n, v):
    p = model.prepare(np.atleast_2d(n))
    v = np.asarray(v, float)
    return np.array([a[0, 0] for a in p.stress(v[None, None, 0], v[None, None, 1],
                                               v[None, None, 2])])


@pytest.mark.parametrize('n, v, gen, capped', TABLE_4_8)
def test_reference_table(n, v, gen, capped):
    n, v = np.array(n, float), np.array(v, float)
    # The table has three decimals; allow rounding of the last one.
    assert np.allclose(generic_stress(n, v), gen, atol=1.5e-3)
    assert np.allclose(prepared_stress(AgarwalRFT(1.0, math.inf), n, v), gen, atol=1.5e-3)
    assert np.allclose(prepared_stress(AgarwalRFT(1.0, 0.4), n, v), capped, atol=1.5e-3)


def test_edge_on_wall_sliding_is_small_and_capped():
    # n = +x, v = +y (docs/design/models-rft.md 4.8 last row):
    # |alpha_gen| ~ 0.07, capped ~ 0.001. The
    # sign of the tiny x part depends on the n_z = 0 tie-break (we take n_d = -n).
    gen = generic_stress(np.array([1.0, 0, 0]), np.array([0, 1.0, 0]))
    assert np.allclose(np.abs(gen), (0.002, 0.068, 0.026), atol=1.5e-3)
    capped = prepared_stress(AgarwalRFT(1.0, 0.4), (1, 0, 0), (0, 1, 0))
    assert np.allclose(np.abs(capped), (0.002, 0.001, 0.000), atol=1.5e-3)


def test_downward_normal_convention():
    n = np.array([[0, 0, 1.0], [0, 0, -1.0], [1.0, 0, 0], [S, 0, -S]])
    nd = downward_normal(n)
    assert np.all(nd[:, 2] <= 0)
    assert np.allclose(nd[2], (-1, 0, 0))  # vertical facet: n_d = -n (public codes)


def random_units(rng, shape):
    x = rng.normal(size=shape + (3,))
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


def test_prepared_form_matches_reference_form_and_scales_with_xi():
    rng = np.random.default_rng(3)
    n = random_units(rng, (50,))
    v = random_units(rng, (20, 50))
    ref = generic_stress(n[None], v)
    p = AgarwalRFT(2.5e5, math.inf).prepare(n)
    got = np.stack(p.stress(v[..., 0], v[..., 1], v[..., 2]), axis=-1)
    assert np.allclose(got, 2.5e5 * ref, rtol=1e-12, atol=1e-9)


def test_friction_cap_limits_tangential_stress():
    rng = np.random.default_rng(4)
    n = random_units(rng, (200,))
    v = random_units(rng, (1, 200))
    p = AgarwalRFT(1.0, 0.3).prepare(n)
    a = np.stack(p.stress(v[..., 0], v[..., 1], v[..., 2]), axis=-1)[0]
    an = np.sum(a * n, axis=1)
    at = np.linalg.norm(a - an[:, None] * n, axis=1)
    assert np.all(at <= 0.3 * np.abs(an) + 1e-12)


def test_no_nan_for_axis_aligned_inputs():
    axes = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1.0]])
    n = np.repeat(axes, 6, axis=0)
    v = np.tile(axes, (6, 1))[None]
    for mu in (0.0, 0.4, math.inf):
        out = AgarwalRFT(1e5, mu).prepare(n).stress(v[..., 0], v[..., 1], v[..., 2])
        assert all(np.all(np.isfinite(a)) for a in out)


@pytest.mark.skipif(not kernels.AVAILABLE, reason='numba not installed')
def test_fused_kernel_matches_numpy():
    from rftgls_core.geometry.mesh import Facets
    from rftgls_core.rft.engine import BuriedBody
    rng = np.random.default_rng(5)
    f = Facets(rng.uniform(-0.05, 0.02, (300, 3)), random_units(rng, (300,)),
               rng.uniform(1e-6, 1e-5, 300))
    for mu in (0.4, math.inf):
        model = AgarwalRFT(6.8e5, mu)
        a = BuriedBody(f, model, ref=(0.01, 0, 0.02), backend='numpy')
        b = BuriedBody(f, model, ref=(0.01, 0, 0.02), backend='numba')
        assert b.fused and not a.fused
        t6 = rng.normal(size=(40, 6))
        t3 = rng.normal(size=(40, 3))
        # numpy against the fused numba kernel: 300 facet terms summed in another order
        # with fused multiply-adds differ by <= (300 + 30) eps sum|term| <= 7e-14 max|W|
        # (sum|term| <= max|W| for these bodies; tests/core/test_kernel_parallel.py)
        w6a, w6b = a.wrench(t6), b.wrench(t6)
        assert np.allclose(w6a, w6b, rtol=1e-12, atol=1e-12 * np.abs(w6a).max())
        w3a, w3b = a.planar_wrench(t3), b.planar_wrench(t3)
        assert np.allclose(w3a, w3b, rtol=1e-12, atol=1e-12 * np.abs(w3a).max())


def test_preparing_a_subset_gives_that_subset_of_the_prepared_constants_bitwise():
    # The engine prepares a pose's mirrored half on its own (the full body only when asked):
    # its constants must be bitwise the rows of the whole body's (vertical and flat facets
    # included: the n_d tie-break and x2 = 0 or 1), so halving changes no wrench.
    rng = np.random.default_rng(12)
    n = rng.normal(size=(300, 3))
    n[:20, 2] = 0.0
    n[20:30] = (0.0, 0.0, -1.0)
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    model = AgarwalRFT(6.8e5, 0.4)
    keep = rng.random(300) < 0.5
    whole, part = model.prepare(n).fused_arrays(), model.prepare(n[keep]).fused_arrays()
    for key in ('n', 'nd', 'poly'):
        assert np.array_equal(whole[key][keep], part[key])
