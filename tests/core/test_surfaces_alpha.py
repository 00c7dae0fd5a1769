"""MATLAB alphaShape semantics of the scipy alpha shape, on known answers.

References: scipy ConvexHull (alpha = inf), brute-force connected components of the kept and
complement tetrahedra (criteria), and the geometric definition of the all-points alpha.
"""
from __future__ import annotations

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import ConvexHull

from rftgls_core.surfaces.alpha_shape import AlphaComplex, alpha_shape

RNG = np.random.default_rng(3)


def _ellipsoid_cloud(n=600, dent=0.0):
    p = RNG.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1, keepdims=True)
    r = 1.0 + 0.02 * RNG.random(n)                         # not exactly cospherical
    if dent:
        r *= 1.0 - dent * np.exp(-((p[:, 0] - 1.0) ** 2) / 0.15)
    return p * r[:, None] * [1.0, 0.8, 0.6]


def _face_set(faces):
    return {tuple(sorted(f)) for f in faces}


@pytest.fixture(scope='module')
def convex_cx():
    return AlphaComplex(_ellipsoid_cloud())


def test_alpha_inf_is_the_convex_hull(convex_cx):
    shp = alpha_shape(convex_cx, np.inf)
    hull = ConvexHull(convex_cx.points)
    assert _face_set(shp.faces) == _face_set(hull.simplices)
    assert shp.topology.closed_genus0


def _volume(cx, keep):
    p = cx.points[cx.simplices[keep]]
    return float(np.abs(np.einsum('ij,ij->i', p[:, 1] - p[:, 0],
                                  np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]))).sum() / 6)


def test_convex_cloud_paper_alpha_gives_nearly_its_hull(convex_cx):
    # The median rule sits in the large-radius tail
    # (docs/design/limit-surfaces.md#the-papers-median-rule): one region,
    # no voids, essentially the hull (a few boundary slivers may stay out).
    crit = convex_cx.criteria()
    shp = alpha_shape(convex_cx, crit.alpha_paper)
    assert shp.regions == 1 and shp.topology.closed_genus0
    hull_vol = ConvexHull(convex_cx.points).volume
    assert _volume(convex_cx, shp.keep) == pytest.approx(hull_vol, rel=0.01)
    # every tetrahedron's volume summed against qhull's: two sums of ~1e4 terms of one sign,
    # each within n eps of the exact volume (2e-12 relative)
    assert _volume(convex_cx, np.ones(convex_cx.n_tets, bool)) == pytest.approx(hull_vol,
                                                                              rel=1e-9)


def test_default_alpha_is_the_all_points_alpha(convex_cx):
    crit = convex_cx.criteria()
    a = crit.alpha_all_points
    assert a in crit.spectrum
    covered = np.zeros(len(convex_cx.points), bool)
    covered[convex_cx.simplices[convex_cx.radii <= a].ravel()] = True
    assert covered.all()
    below = crit.spectrum[crit.spectrum < a].max()
    covered[:] = False
    covered[convex_cx.simplices[convex_cx.radii <= below].ravel()] = True
    assert not covered.all()
    assert crit.alpha_one_region >= a
    assert np.all(np.diff(crit.spectrum) < 0)             # descending, distinct


def test_dented_cloud_keeps_its_dent_at_small_alpha():
    cx = AlphaComplex(_ellipsoid_cloud(1500, dent=0.35))
    crit = cx.criteria()
    hull_vertices = set(ConvexHull(cx.points).vertices)
    shp = alpha_shape(cx, crit.alpha_one_region)
    boundary_vertices = set(np.unique(shp.faces))
    # Points inside the dent are hidden by the hull but lie on the small-alpha boundary.
    assert len(boundary_vertices - hull_vertices) > 20
    big = alpha_shape(cx, np.inf)
    assert set(np.unique(big.faces)) == hull_vertices


def test_criteria_match_brute_force_components(convex_cx):
    cx = convex_cx
    crit = cx.criteria()
    t = cx.n_tets
    i = np.repeat(np.arange(t), 4)
    j = cx.neighbors.ravel()
    m = j >= 0
    i, j = i[m], j[m]
    hull = np.flatnonzero((cx.neighbors < 0).any(axis=1))
    for k in np.linspace(0, len(crit.spectrum) - 1, 25).astype(int):
        a = crit.spectrum[k]
        keep = cx.radii <= a
        mk = keep[i] & keep[j]
        _, lab = connected_components(coo_matrix((np.ones(mk.sum()), (i[mk], j[mk])),
                                                 shape=(t, t)), directed=False)
        regions = len(np.unique(lab[keep]))
        mc = ~keep[i] & ~keep[j]
        h = hull[~keep[hull]]
        ii, jj = np.concatenate([i[mc], h]), np.concatenate([j[mc], np.full(len(h), t)])
        _, lab = connected_components(coo_matrix((np.ones(len(ii)), (ii, jj)),
                                                 shape=(t + 1, t + 1)), directed=False)
        voids = len(set(lab[np.flatnonzero(~keep)]) - {lab[t]})
        covered = np.zeros(len(cx.points), bool)
        covered[cx.simplices[keep].ravel()] = True
        assert (bool(crit.all_points[k]), int(crit.regions[k]), int(crit.voids[k])) == \
            (bool(covered.all()), regions, voids), a


def test_boundary_faces_point_outward(convex_cx):
    shp = alpha_shape(convex_cx, convex_cx.criteria().alpha_paper)
    p = convex_cx.points
    f = shp.faces
    n = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    centre = p.mean(axis=0)
    assert np.all(np.einsum('ij,ij->i', n, p[f].mean(axis=1) - centre) > 0)
