"""Accuracy of the representations on analytic limit surfaces
(docs/design/limit-surfaces.md#synthetic-test-surfaces).

References: `synthetic.PNormGLS.exact_capacity` (brentq on the dual q-norm, independent of
every representation) and its exact twist A^-1 grad||y||_q; for the dented case the exact
value is the dent factor times the convex exact value (radial dent, see synthetic.py).
Twist angles are measured in the scaled metric.
"""
from __future__ import annotations

import numpy as np
import pytest

from rftgls_core.surfaces.alpha_shape import AlphaShapeSurface
from rftgls_core.surfaces.direct import DirectSurface
from rftgls_core.surfaces.ellipsoid import EllipsoidSurface
from rftgls_core.surfaces.synthetic import convex_case, dented_case
from rftgls_core.surfaces.twist_mesh import TwistMeshSurface, TwistSphere
from rftgls_core.types import Status

PHIS = np.linspace(-1.35, 1.35, 19)   # the tug region Fx < 0


def _errors(case, results):
    cap, ang = [], []
    for phi, r in zip(PHIS, results):
        assert r.status is Status.OK, r
        exact = case.exact_capacity(phi)
        cap.append((r.capacity_N - exact) / exact)
        ang.append(np.degrees(np.arccos(np.clip(case.exact_twist_scaled(phi)
                                                @ np.asarray(r.slip_twist_scaled), -1, 1))))
    return np.array(cap), np.array(ang)


@pytest.fixture(scope='module')
def convex():
    return convex_case()


@pytest.fixture(scope='module')
def dented():
    return dented_case()


@pytest.mark.parametrize('which', ['convex', 'dented'])
def test_twist_mesh_within_1pct_and_2deg_never_over(which, request):
    case = request.getfixturevalue(which)
    surf = TwistMeshSurface(2000).fit(case.problem)
    assert surf.fit_info.diagnostics['folds'] == 0
    cap, ang = _errors(case, surf.capacity_many(PHIS))
    assert np.max(np.abs(cap)) < 0.01
    assert np.max(cap) < 0.01            # never above the exact value by more than 1 %
    assert np.max(ang) < 2.0
    # The raw slip twist is the scaled one mapped back.
    r = surf.capacity(0.3)
    sc = case.problem.scaling
    np.testing.assert_allclose(sc.twist_to_scaled(np.array(r.slip_twist)), r.slip_twist_scaled,
                               atol=1e-12)


def test_twist_mesh_connectivity_reused_across_poses(convex, dented):
    sphere = TwistSphere.build(1000)
    a = TwistMeshSurface(sphere=sphere).fit(convex.problem)
    b = TwistMeshSurface(sphere=sphere).fit(dented.problem)
    assert a.sphere.faces is b.sphere.faces
    assert a.capacity(0.3).ok and b.capacity(0.3).ok
    assert b.capacity(0.3).capacity_N < a.capacity(0.3).capacity_N   # the dent is there


@pytest.mark.parametrize('which', ['convex', 'dented'])
def test_direct_matches_exact(which, request):
    case = request.getfixturevalue(which)
    surf = DirectSurface().fit(case.problem)
    cap, ang = _errors(case, surf.capacity_many(PHIS))
    assert np.max(np.abs(cap)) < 1e-6
    assert np.max(ang) < 1e-3
    # Few batched wrench_fn calls per query (bracketing mesh + Newton iterations).
    calls0 = surf.n_wrench_calls
    surf.capacity(0.2)
    assert surf.n_wrench_calls - calls0 <= 15


def test_ellipsoid_is_exact_on_an_ellipsoid_and_a_fair_baseline_otherwise():
    ell = convex_case(p=2.0)                 # q = 2: the exact surface is an ellipsoid
    cap, ang = _errors(ell, EllipsoidSurface().fit(ell.problem).capacity_many(PHIS))
    assert np.max(np.abs(cap)) < 1e-8 and np.max(ang) < 1e-4
    # On the boxier p = 1.6 surface the ellipsoid is only a model: ~15 % and ~12 deg worst case
    # here (documented limitation;
    # docs/design/limit-surfaces.md#ellipsoid-lg04: 4.8 % on a rounder one).
    case = convex_case()
    cap, ang = _errors(case, EllipsoidSurface().fit(case.problem).capacity_many(PHIS))
    assert np.max(np.abs(cap)) < 0.2 and np.max(ang) < 20.0


@pytest.mark.parametrize('which', ['convex', 'dented'])
def test_alpha_shape_paper_rule_on_gentle_surfaces(which, request):
    case = request.getfixturevalue(which)
    surf = AlphaShapeSurface(2000).fit(case.problem)
    assert surf.fit_info.status is Status.OK, surf.fit_info
    cap, ang = _errors(case, surf.capacity_many(PHIS))
    assert np.max(np.abs(cap)) < 0.01 and np.max(ang) < 2.0
