"""Batched RFT engine: analytic integrals and properties (rate independence, linearity in
depth and area, mirror symmetry, zero force above the surface, moment transport)."""
import math

import numpy as np
import pytest
from scipy import integrate

from rftgls_core.geometry.mesh import Facets
from rftgls_core.geometry.shapes import icosphere
from rftgls_core.rft.agarwal import AgarwalRFT
from rftgls_core.rft.engine import BuriedBody
from rftgls_core.robots.presets import minirquad, prototype
from rftgls_core.types import AnchorState

BACKENDS = ['numpy', 'auto']


def horizontal_facet(depth, area, normal_z=-1.0):
    return Facets(np.array([[0.0, 0.0, -depth]]), np.array([[0.0, 0.0, normal_z]]),
                  np.array([area]))


@pytest.mark.parametrize('backend', BACKENDS)
def test_plate_pushed_down_reference(backend):
    # docs/design/models-rft.md 4.8: a 2 x 2 cm horizontal plate at 5 cm depth pushed down,
    # xi_n = 3.771e5 N/m^3 gives 6.60 N (= 0.875 xi_n A d).
    body = BuriedBody(horizontal_facet(0.05, 4e-4), AgarwalRFT(3.771e5, 0.4), backend=backend)
    f = body.wrench(np.array([0, 0, -1.0, 0, 0, 0]))
    assert f[2] == pytest.approx(6.60, abs=0.005)
    assert np.allclose(f[[0, 1]], 0, atol=1e-12)


@pytest.mark.parametrize('backend', BACKENDS)
def test_linear_in_depth_and_area(backend):
    model = AgarwalRFT(5e5, 0.4)
    t = np.array([0.3, 0.0, -1.0, 0.0, 0.0, 0.0])
    base = BuriedBody(horizontal_facet(0.02, 1e-4), model, backend=backend).wrench(t)
    deeper = BuriedBody(horizontal_facet(0.06, 1e-4), model, backend=backend).wrench(t)
    wider = BuriedBody(horizontal_facet(0.02, 5e-4), model, backend=backend).wrench(t)
    # one facet: depth and area enter as one factor each, so the two sides differ by the
    # rounding of that product (and of 0.06 against 3 * 0.02): a few eps
    assert np.allclose(deeper[:3], 3 * base[:3], rtol=1e-12)
    assert np.allclose(wider[:3], 5 * base[:3], rtol=1e-12)


@pytest.mark.parametrize('backend', BACKENDS)
def test_rate_independent(backend):
    posed = minirquad().pose(AnchorState.from_degrees(0.02, 5, -20, 30))
    body = BuriedBody(posed.facets, AgarwalRFT(6.8e5, 0.4), ref=posed.ref, backend=backend)
    rng = np.random.default_rng(0)
    t = rng.normal(size=(20, 6))
    w = body.wrench(t)
    # each twist is normalised first: k t / |k t| and t / |t| differ by a few eps per
    # component, which the sum over n < 1,000 buried facets carries at most n eps of sum|term|
    # (<= 2e-13 of max|W|, tests/core/test_kernel_parallel.py)
    for k in (1e-3, 7.0, 1e4):
        assert np.allclose(body.wrench(k * t), w, rtol=1e-10, atol=1e-12 * np.abs(w).max())


def test_zero_force_above_surface():
    posed = minirquad().pose(AnchorState.from_degrees(0.30, 0, 0, 0))  # 30 cm up: nothing buried
    body = BuriedBody(posed.facets, AgarwalRFT(6.8e5, 0.4), ref=posed.ref)
    assert body.facets_active == 0 and body.facets_total == len(posed.facets)
    assert np.all(body.planar_wrench(np.array([[1.0, -1.0, 3.0], [0, 1.0, 0]])) == 0.0)


@pytest.mark.parametrize('robot', [minirquad, prototype])
@pytest.mark.parametrize('pull', ['forward', 'backward'])
def test_mirror_shortcut_matches_full_computation(robot, pull):
    rng = np.random.default_rng(11)
    model = AgarwalRFT(6.8e5, 0.4)
    for _ in range(4):
        state = AnchorState(rng.uniform(0.0, 0.04), *np.radians(rng.uniform(-30, 30, 3)))
        posed = robot().pose(state, pull)
        body = BuriedBody(posed.facets, model, ref=posed.ref, mirror_y=posed.mirror_y)
        t = rng.normal(size=(50, 3))
        full = body.planar_wrench(t, use_symmetry=False)
        half = body.planar_wrench(t)
        # the half with doubled weights against both halves: the same terms summed in
        # another order, <= (n + 30) eps sum|term| with n < 1,000 buried facets, i.e. <= 3e-13 of
        # max|W| (measured 3e-15); 1e-9 leaves room for the mirrored pairs' rounding in posing
        assert np.abs(full - half).max() <= 1e-9 * np.abs(full).max()
        # Lateral force and roll/yaw moments cancel between mirror legs.
        t6 = np.column_stack([t[:, 0], 0 * t[:, 0], t[:, 1], 0 * t[:, 0], t[:, 2], 0 * t[:, 0]])
        w6 = body.wrench(t6)
        # the 6D and the planar kernel on the same facets, summed in another order: <= 3e-13 of
        # max|W| as above (measured 1.4e-13 relative on the smallest entries)
        assert np.allclose(w6[:, [0, 2, 4]], full, rtol=1e-12, atol=1e-12 * np.abs(full).max())
        assert np.abs(w6[:, [1, 3, 5]]).max() <= 1e-9 * np.abs(w6).max()


def test_moment_transport_between_reference_points():
    posed = prototype().pose(AnchorState.from_degrees(0.01, 10, 20, -20))
    model = AgarwalRFT(3.8e5, 0.4)
    a, b = np.array([0.0, 0.0, 0.01]), np.array([0.05, 0.02, -0.03])
    rng = np.random.default_rng(2)
    for _ in range(10):
        v_a, omega = rng.normal(size=3), rng.normal(size=3) * 20
        v_b = v_a + np.cross(omega, b - a)  # same rigid motion described at b
        wa = BuriedBody(posed.facets, model, ref=a).wrench(np.r_[v_a, omega])
        wb = BuriedBody(posed.facets, model, ref=b).wrench(np.r_[v_b, omega])
        # the same motion at another reference point: each facet's velocity is rebuilt from
        # (v, omega) with a cross product (a few eps relative), so forces agree to the sum's
        # n eps sum|term| (< 1e-12 of max|W|); moments also go through the transport
        # r x F of forces ~1 N at ~0.05 m
        assert np.allclose(wa[:3], wb[:3], rtol=1e-10, atol=1e-12 * np.abs(wa[:3]).max())
        assert np.allclose(wb[3:], wa[3:] + np.cross(a - b, wa[:3]), rtol=1e-9, atol=1e-12)


def test_facet_at_rest_and_bad_twists():
    # Pure rotation about the facet's own centroid: the facet has no velocity, no force.
    f = horizontal_facet(0.03, 1e-4)
    body = BuriedBody(f, AgarwalRFT(5e5, 0.4), ref=(0.0, 0.0, -0.03))
    w = body.wrench(np.array([0, 0, 0, 0, 1.0, 0]))
    assert np.all(np.isfinite(w)) and np.all(w == 0.0)
    with pytest.raises(ValueError, match='NaN'):
        body.wrench(np.array([np.nan, 0, 0, 0, 0, 0]))
    with pytest.raises(ValueError, match='zero twist'):
        body.planar_wrench(np.zeros(3))


def sphere_down_quadrature(xi_n, mu, radius, depth):
    """F_z on a sphere moving straight down, by 1D quadrature over the polar angle.

    Independent of meshes: alpha at each surface point from the stress model, depth-linear,
    integrated over the leading (lower) hemisphere.
    """
    prepared = lambda n: AgarwalRFT(xi_n, mu).prepare(n)

    def integrand(theta):
        n = np.array([[math.sin(theta), 0.0, math.cos(theta)]])
        az = prepared(n).stress(np.zeros((1, 1)), np.zeros((1, 1)), -np.ones((1, 1)))[2][0, 0]
        z = -depth + radius * math.cos(theta)
        return az * (-z) * 2 * math.pi * radius ** 2 * math.sin(theta)

    return integrate.quad(integrand, math.pi / 2, math.pi, epsabs=0, epsrel=1e-10, limit=200)[0]


@pytest.mark.parametrize('mu, published', [(math.inf, 13.82), (0.4, 10.64), (0.2, 9.26)])
def test_sphere_quadrature_matches_published(mu, published):
    # docs/design/models-rft.md 4.8: R = 1 cm, centre depth 3 cm, xi_n = 1 N/cm^3, moving down.
    assert sphere_down_quadrature(1e6, mu, 0.01, 0.03) == pytest.approx(published, abs=0.006)


def test_icosphere_converges_to_sphere_integral():
    exact = sphere_down_quadrature(1e6, 0.4, 0.01, 0.03)
    errors = []
    for sub in (2, 3, 4, 5):
        mesh = icosphere(0.01, sub)
        f = mesh.facets().transformed(np.eye(3), [0.0, 0.0, -0.03])
        fz = BuriedBody(f, AgarwalRFT(1e6, 0.4)).wrench(np.array([0, 0, -1.0, 0, 0, 0]))[2]
        errors.append(abs(fz - exact) / exact)
    # Facet-centroid sampling converges slowly (leading-edge cut at the equator) but steadily.
    assert all(e2 < e1 for e1, e2 in zip(errors, errors[1:])), errors
    assert errors[-1] < 0.005, errors
