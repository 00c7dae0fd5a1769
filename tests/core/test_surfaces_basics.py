"""Scaling, twist sampling, ray casting and mesh checks of the limit-surface layer.

References here are closed-form geometry (octahedron and cube distances, power pairing by
construction), never the code under test.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from rftgls_core.surfaces.diagnostics import max_power_check, mesh_topology
from rftgls_core.surfaces.raycast import all_hits, cast_rays, prepare_mesh, winding_number
from rftgls_core.surfaces.sampling import fibonacci_sphere
from rftgls_core.surfaces.scaling import Scaling, choose_scaling
from rftgls_core.surfaces.synthetic import PNormGLS
from rftgls_core.surfaces.twist_mesh import TwistSphere
from rftgls_core.types import pull_direction

RNG = np.random.default_rng(7)


def test_power_pairing_is_kept_by_scaling():
    # t.W and ts.Ws must be proportional with a positive factor (power pairing invariant).
    sc = Scaling(force_N=4.0, length_m=0.03)
    t = RNG.normal(size=(50, 3))
    w = RNG.normal(size=(50, 3)) * [3.0, 5.0, 0.05]
    ratio = np.einsum('ij,ij->i', sc.twist_to_scaled(t), sc.wrench_to_scaled(w))
    raw = np.einsum('ij,ij->i', t, w)
    k = ratio / raw
    assert np.all(k > 0)
    np.testing.assert_allclose(k, 1.0 / np.linalg.norm(t * sc.diag, axis=1), rtol=1e-12)


def test_scaling_round_trips():
    sc = Scaling(2.0, 0.1)
    w = RNG.normal(size=(10, 3))
    np.testing.assert_allclose(sc.wrench_from_scaled(sc.wrench_to_scaled(w)), w, rtol=1e-14)
    t = RNG.normal(size=(10, 3))
    back = sc.twist_from_scaled(sc.twist_to_scaled(t))
    np.testing.assert_allclose(back, t / np.linalg.norm(t, axis=1, keepdims=True), atol=1e-14)
    with pytest.raises(ValueError):
        Scaling(0.0, 1.0)


def test_half_range_scaling_from_data():
    # Cloud spanning Fx in [-3, 3], Fz in [-1, 9], My in [-0.05, 0.05]: s_F = 5, L_c = 0.01.
    w = np.array([[-3, -1, -0.05], [3, 9, 0.05], [0, 0, 0.0]])
    sc = Scaling.from_wrenches(w)
    assert sc.force_N == pytest.approx(5.0)
    assert sc.length_m == pytest.approx(0.01)
    # The pilot-based helper recovers the same scales for the analytic surface.
    g = PNormGLS(offset=(0.0, 0.0, 0.0))
    sc2 = choose_scaling(g.wrench, length_guess_m=0.05, n_pilot=2000)
    assert sc2.force_N == pytest.approx(5.0, rel=0.01)
    assert sc2.length_m == pytest.approx(0.01, rel=0.02)


def test_fibonacci_sphere_is_unit_distinct_and_balanced():
    p = fibonacci_sphere(2000)
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 1.0, atol=1e-14)
    assert len(np.unique(np.round(p, 9), axis=0)) == 2000
    assert np.linalg.norm(p.mean(axis=0)) < 1e-3
    scaled = fibonacci_sphere(100)
    raw = Scaling(5.0, 0.01).twist_from_scaled(scaled)
    np.testing.assert_allclose(Scaling(5.0, 0.01).twist_to_scaled(raw), scaled, atol=1e-12)


def test_pull_direction_convention():
    assert np.allclose(pull_direction(0.0), (-1.0, 0.0, 0.0))
    assert np.allclose(pull_direction(math.pi / 2), (0.0, 1.0, 0.0))


def _octahedron(r=2.0):
    v = np.array([[r, 0, 0], [-r, 0, 0], [0, r, 0], [0, -r, 0], [0, 0, r], [0, 0, -r]], float)
    f = []
    for x in (0, 1):
        for y in (2, 3):
            for z in (4, 5):
                f.append([x, y, z])
    from rftgls_core.surfaces.twist_mesh import orient_outward
    return v, orient_outward(v, np.array(f))


def test_ray_through_face_edge_and_vertex_counts_once():
    v, f = _octahedron(2.0)
    mesh = prepare_mesh(v, f)
    dirs = np.array([[1, 1, 1], [1, 1, 0], [1, 0, 0], [0, 0, -1]], float)
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    h = cast_rays(mesh, dirs)
    # Face (x+y+z = 2): distance 2/sqrt(3); edge midpoint (1, 1, 0): sqrt(2); vertices: 2.
    np.testing.assert_allclose(h.s, [2 / math.sqrt(3), math.sqrt(2), 2.0, 2.0], rtol=1e-12)
    assert list(h.n_hits) == [1, 1, 1, 1]
    assert list(h.n_raw) == [1, 2, 4, 4]
    assert list(h.on_edge) == [False, True, True, True]
    np.testing.assert_allclose(h.bary.sum(axis=1), 1.0)
    # The barycentric point reproduces the hit.
    for k in range(4):
        p = h.bary[k] @ v[f[h.face[k]]]
        np.testing.assert_allclose(p, h.s[k] * dirs[k], atol=1e-12)


def test_ray_from_outside_crosses_twice_and_winding():
    v, f = _octahedron(1.0)
    origin = np.array([-3.0, 0.1, 0.05])
    mesh = prepare_mesh(v, f, origin)
    h = cast_rays(mesh, np.array([1.0, 0.0, 0.0]))
    assert h.n_hits[0] == 2
    s, faces, _ = all_hits(mesh, np.array([1.0, 0.0, 0.0]))
    assert len(s) == 2 and s[0] < s[1]
    assert winding_number(v, f) == pytest.approx(1.0)
    assert winding_number(v, f, origin) == pytest.approx(0.0, abs=1e-12)



def test_winding_number_loop_agrees_with_the_numpy_expression():
    """The compiled loop sums the triangles' solid angles in order, numpy pairwise, and both
    take arctan2 from their own libraries: they agree to a few ulp per triangle of the sum,
    F x 1e-16 with F = 996 triangles, within 1e-12. Inside, outside and near the surface of a
    lumpy closed mesh."""
    from rftgls_core.surfaces.mesh_loops import HAVE_NUMBA
    from rftgls_core.surfaces.raycast import winding_number_numpy
    if not HAVE_NUMBA:
        pytest.skip('numba not installed: winding_number is the numpy expression')
    rng = np.random.default_rng(5)
    sph = TwistSphere.build(500)
    v = sph.twists_scaled * (1.0 + 0.3 * rng.random((sph.n, 1)))
    for p in [None, 0.99 * v[3], *rng.normal(size=(10, 3))]:
        w = winding_number(v, sph.faces, p)
        assert w == pytest.approx(winding_number_numpy(v, sph.faces, p), abs=1e-12)
    assert winding_number(v, sph.faces) == pytest.approx(1.0)


def test_sphere_triangulation_is_closed_genus0_and_reusable():
    sph = TwistSphere.build(500)
    assert TwistSphere.build(500) is sph          # cached: one connectivity for all poses
    topo = mesh_topology(sph.faces)
    assert topo.closed_genus0 and topo.n_faces == 2 * 500 - 4
    # Outward: every face normal points away from the centre.
    p = sph.twists_scaled
    n = np.cross(p[sph.faces[:, 1]] - p[sph.faces[:, 0]], p[sph.faces[:, 2]] - p[sph.faces[:, 0]])
    assert np.all(np.einsum('ij,ij->i', n, p[sph.faces].mean(axis=1)) > 0)


def test_max_power_check_convex_has_no_violation_dent_has_some():
    g = PNormGLS()
    sc = Scaling(5.0, 0.01)
    scaled = fibonacci_sphere(600)
    ws = sc.wrench_to_scaled(g.wrench(sc.twist_from_scaled(scaled)))
    rep = max_power_check(scaled, ws, tol=1e-9)
    assert rep.fraction == 0.0
    bent = ws * (1.0 - 0.4 * np.exp(-((scaled[:, 0] + 1.0) / 0.3) ** 2))[:, None]
    assert max_power_check(scaled, bent).fraction > 0.0


def test_cross_rows_is_np_cross_bitwise():
    # The solvers' row-wise cross product replaces np.cross in hot loops (newton, raycast,
    # warm); it must give the very same numbers, or maps and warm answers would drift.
    from rftgls_core.surfaces.newton import cross_rows
    rng = np.random.default_rng(3)
    for n in (1, 2, 7, 1000):
        a = rng.normal(size=(n, 3)) * 10.0 ** rng.uniform(-8, 8, (n, 1))
        b = rng.normal(size=(n, 3))
        assert np.array_equal(cross_rows(a, b), np.cross(a, b))


def test_row_norms_is_np_linalg_norm_bitwise():
    # row_norms replaces np.linalg.norm(x, axis=-1) in the solvers' hot loops with its own
    # arithmetic (square root of the reduced squares): the very same numbers, any shape.
    from rftgls_core.surfaces.newton import row_norms
    rng = np.random.default_rng(4)
    for shape in ((1, 3), (7, 3), (1000, 3), (200, 2), (5, 2, 2), (3,)):
        x = rng.normal(size=shape) * 10.0 ** rng.uniform(-8, 8, shape)
        for keep in (False, True):
            got, want = row_norms(x, keep), np.linalg.norm(x, axis=-1, keepdims=keep)
            assert np.shape(got) == np.shape(want) and np.array_equal(got, want)
