"""LiTreersRFT: Li's 2D fit in Treers' 3D decomposition (rft/treers.py),
docs/design/models-rft.md 2-3."""
from __future__ import annotations

import json
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rftgls_core.geometry.shapes import icosphere
from rftgls_core.rft.li import GENERIC, li_alpha
from rftgls_core.rft.treers import F1_C, F23_D, LiTreersRFT, f1, f23

ZETA = 3.3e5                     # N/m^3 (0.33 N/cm^3, Treers' glass beads,
                                 # docs/design/models-rft.md 2.4)


def stress(n, v, model=None):
    """Stress (3,) for one normal and one velocity direction."""
    model = model or LiTreersRFT(ZETA)
    n = np.asarray(n, float)[None, :]
    v = np.asarray(v, float)
    out = model.prepare(n).stress(*(np.full((1, 1), c) for c in v))
    return np.array([c[0, 0] for c in out])


def unit(*xyz):
    a = np.array(xyz, float)
    return a / np.linalg.norm(a)


# --------------------------------------------------------------------- weights (section 3.3)

def test_weights_table():
    # docs/design/models-rft.md 3.3: phi in degrees -> f1(sin phi), f23(cos phi), 4 decimals
    phi = np.radians([0, 15, 30, 45, 60, 75, 90])
    np.testing.assert_allclose(f1(np.sin(phi)),
                               [0, 0.1785, 0.5946, 0.8813, 0.9709, 0.9949, 1], atol=5e-5 + 1e-12)
    np.testing.assert_allclose(f23(np.cos(phi)),
                               [1, 0.9699, 0.8955, 0.7986, 0.6830, 0.5257, 0], atol=5e-5 + 1e-12)


def test_weights_end_points_and_domain():
    # docs/design/models-rft.md 3.3: both are 0 at 0 and 1 at 1; artanh stays finite on [0, 1]
    assert f1(0.0) == pytest.approx(0, abs=1e-14) and f1(1.0) == pytest.approx(1, abs=1e-14)
    assert f23(0.0) == pytest.approx(0, abs=1e-14) and f23(1.0) == pytest.approx(1, abs=1e-14)
    x = np.array([-0.5, 0.0, 1.0, 1.0 + 1e-9, 7.0])
    assert np.all(np.isfinite(f1(x))) and np.all(np.isfinite(f23(x)))
    assert len(F1_C) == 4 and len(F23_D) == 4


# --------------------------------------------------------------- reference stresses (2.6, 3.2)

@pytest.mark.parametrize('n', [(0, 0, -1), unit(1e-4, 0, -1), unit(0, 2e-4, -1)])
def test_horizontal_plate_pushed_down(n):
    # 2.6 (0, 90 deg): alpha_z = 1.000 -> stress zeta (0, 0, 1); exact for the exact normal
    s = stress(n, (0, 0, -1))
    atol = 1e-12 * ZETA if tuple(n) == (0, 0, -1) else 1e-3 * ZETA
    np.testing.assert_allclose(s, [0, 0, ZETA], atol=atol)


@pytest.mark.parametrize('n, v, expected', [
    ((0, 0, 1), (0, 0, 1), (0, 0, -0.250)),             # 2.6 (0, -90): extraction resisted
    ((0, 0, -1), (1, 0, 0), (-0.136, 0, 0.375)),        # 2.6 (0, 0): drag + lift
    ((0, 0, -1), (0, 1, 0), (0, -0.136, 0.375)),        # same, flat facet follows v (3.2 s5)
    ((0, 0, -1), unit(-1, -1, 0), (0.136 / math.sqrt(2), 0.136 / math.sqrt(2), 0.375)),
    ((1, 0, 0), (1, 0, 0), (-0.370, 0, 0.037)),         # 2.6 (90, 0): vertical wall pushed
    ((0, -1, 0), (0, -1, 0), (0, 0.370, 0.037)),
    ((1, 0, 0), (0, 0, -1), (0, 0, 0.128)),             # 2.6 (90, 90): wall sliding down
    (unit(1, 0, -1), (0, 0, -1), (-0.219, 0, 0.564)),   # 2.6 (45, 90)
    (unit(1, 0, -1), (1, 0, 0), (-0.341, 0, 0.363)),    # 2.6 (45, 0)
    (unit(1, 0, 1), (1, 0, 0), (-0.165, 0, 0.049)),     # 2.6 (-45, 0)
    ((1, 0, 0), (0, 1, 0), (0, -0.136, 0)),             # v along e1: alpha_1 = 0.136 (3.4)
    ((1, 0, 0), (0, -1, 0), (0, 0.136, 0)),
])
def test_reference_stresses(n, v, expected):
    np.testing.assert_allclose(stress(n, v) / ZETA, expected, atol=5e-4 + 1e-12)


def _treers_reference(n, v, alpha1_ratio=GENERIC.drag):
    """docs/design/models-rft.md 3.2 steps 5-10 written out literally (angles via atan2),
    zeta = 1."""
    z = np.array([0.0, 0.0, 1.0])
    if abs(n[2]) < 1 - 1e-3:
        e2 = np.array([n[0], n[1], 0.0])
    else:
        e2 = np.array([v[0], v[1], 0.0])
    e2 /= np.linalg.norm(e2)
    e1 = np.cross(e2, z)
    v1 = (v @ e1) * e1
    v23 = v - v1
    beta = math.atan2(n[2], n @ e2) + math.pi / 2
    gamma = -math.atan2(v23[2], v23 @ e2)
    ax, az = li_alpha(beta, gamma)
    vt = np.linalg.norm(v1)
    vn = np.linalg.norm(v23)
    return (-f1(vt) * alpha1_ratio * np.sign(v @ e1) * e1 - f23(vn) * ax * e2
            + f23(vn) * az * z)


def test_matches_literal_treers_algorithm():
    rng = np.random.default_rng(11)
    normals = rng.normal(size=(400, 3))
    normals[:40] = [0.0, 0.0, -1.0] + 1e-4 * rng.normal(size=(40, 3))   # near-horizontal
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    vel = rng.normal(size=(400, 3))
    vel /= np.linalg.norm(vel, axis=1, keepdims=True)
    vel *= np.sign(np.einsum('ij,ij->i', normals, vel))[:, None]       # leading facets
    prepared = LiTreersRFT(1.0).prepare(normals)
    got = np.stack(prepared.stress(*vel.T[:, None, :]), axis=-1)[0]
    ref = np.array([_treers_reference(n, v) for n, v in zip(normals, vel)])
    np.testing.assert_allclose(got, ref, atol=1e-12)


def test_alpha1_ratio_reproduces_public_code_choice():
    # docs/design/models-rft.md 3.4: Treers' code uses aY ~ 0.2035;
    # only the out-of-plane part changes
    model = LiTreersRFT(1.0, alpha1_ratio=0.2035)
    n, v = unit(1, 0.3, -0.5), unit(0.6, 1.0, -0.2)
    np.testing.assert_allclose(stress(n, v, model), _treers_reference(n, v, 0.2035),
                               atol=1e-12)
    np.testing.assert_allclose(stress((1, 0, 0), (0, 1, 0), model), [0, -0.2035, 0])


def test_sphere_forces_match_models_rft_2_6():
    # docs/design/models-rft.md 2.6: sphere R = 1 cm, centre 3 cm deep, generic, zeta = 1 N/cm^3,
    # facet-centroid sums on a 20480-triangle icosphere: down 9.644 N, +x (-4.485, 0, 2.404) N,
    # up -1.765 N (analytic down: 9.664 N)
    mesh = icosphere(0.01, 5).transformed(np.eye(3), [0.0, 0.0, -0.03])
    f = mesh.facets()
    prepared = LiTreersRFT(1e6).prepare(f.normals)
    vel = np.array([[0, 0, -1], [1, 0, 0], [0, 0, 1]], float)
    ax, ay, az = prepared.stress(*(np.repeat(vel[:, [k]], len(f), 1) for k in range(3)))
    lead = vel @ f.normals.T > 0
    w = lead * (-f.centroids[:, 2] * f.areas)
    force = np.stack([(ax * w).sum(1), (ay * w).sum(1), (az * w).sum(1)], axis=1)
    np.testing.assert_allclose(force, [[0, 0, 9.644], [-4.485, 0, 2.404], [0, 0, -1.765]],
                               atol=5e-4 + 1e-9)


# ------------------------------------------------------------------- symmetry and robustness

def test_rotation_about_vertical_axis_is_equivariant():
    rng = np.random.default_rng(5)
    n = rng.normal(size=(200, 3))
    n[:20] = [0, 0, 1]
    n[20:40] = [0, 0, -1]
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    v = rng.normal(size=(200, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    a = 0.7
    rz = np.array([[math.cos(a), -math.sin(a), 0], [math.sin(a), math.cos(a), 0], [0, 0, 1]])
    model = LiTreersRFT(ZETA)
    s = np.stack(model.prepare(n).stress(*v.T[:, None, :]), -1)[0]
    s_rot = np.stack(model.prepare(n @ rz.T).stress(*(v @ rz.T).T[:, None, :]), -1)[0]
    np.testing.assert_allclose(s_rot, s @ rz.T, atol=1e-9 * ZETA)


AXES = [tuple(float(x) for x in row) for row in np.vstack([np.eye(3), -np.eye(3)])]
directions = st.one_of(
    st.sampled_from(AXES),
    st.tuples(*(st.floats(-1, 1, allow_nan=False) for _ in range(3))).filter(
        lambda t: math.hypot(*t) > 1e-6).map(lambda t: tuple(unit(*t))),
    # almost axis-aligned: tiny components that defeat naive divisions
    st.tuples(st.sampled_from(AXES), st.floats(-1e-13, 1e-13), st.floats(-1e-13, 1e-13)).map(
        lambda t: tuple(unit(t[0][0] + t[1], t[0][1] + t[2], t[0][2]))),
)


@settings(max_examples=300, deadline=None)
@given(n=directions, v=directions)
def test_never_nan_and_bounded(n, v):
    s = stress(n, v)
    assert np.all(np.isfinite(s))
    # no coefficient combination exceeds ~1.3 zeta (Li's fit peaks at 1.0 for penetration)
    assert np.linalg.norm(s) <= 1.5 * ZETA


def test_axis_aligned_grid_and_zero_velocity():
    axes = np.array(AXES)
    normals = np.repeat(axes, len(axes), axis=0)
    vel = np.tile(axes, (len(axes), 1))
    prepared = LiTreersRFT(ZETA).prepare(normals)
    out = np.stack(prepared.stress(*vel.T[:, None, :]), -1)
    assert np.all(np.isfinite(out))
    zero = np.zeros((2, len(normals)))
    assert all(np.all(c == 0) for c in prepared.stress(zero, zero, zero))
    # a zero normal (degenerate facet) is finite too
    s = LiTreersRFT(ZETA).prepare(np.zeros((1, 3))).stress(*np.ones((3, 1, 1)))
    assert all(np.isfinite(c).all() for c in s)


def test_continuous_through_the_out_of_plane_sign():
    # sign(v . e1) is weighted by f1(|v . e1|) -> 0, so crossing v . e1 = 0 is continuous
    n = unit(1, 0, -0.3)
    a = stress(n, unit(1, 1e-9, -0.2))
    b = stress(n, unit(1, -1e-9, -0.2))
    np.testing.assert_allclose(a, b, atol=1e-6 * ZETA)


def test_shapes_and_broadcasting():
    normals = np.array([[0, 0, -1.0], [1, 0, 0], unit(1, 1, -1)])
    v = np.random.default_rng(2).normal(size=(3, 5, 3))
    v /= np.linalg.norm(v, axis=0, keepdims=True)
    out = LiTreersRFT(ZETA).prepare(normals).stress(*v)
    assert all(c.shape == (5, 3) and c.dtype == float for c in out)


# --------------------------------------------------------------------- parameters and units

def test_parameters_and_describe():
    model = LiTreersRFT(ZETA)
    assert model.name == 'li'
    assert model.alpha1 == pytest.approx(0.136 * ZETA)
    d = json.loads(json.dumps(model.describe()))
    assert d['zeta_N_per_m3'] == ZETA and d['coefficients'] == 'generic'


def test_poppy_sets_convert_n_per_cm3_to_si():
    # docs/design/models-rft.md 1 and 2.3-2.4:
    # the LP/CP numbers are N/cm^3 and 1 N/cm^3 = 1e6 N/m^3, so
    # the default zeta = 1e6 N/m^3 reproduces them in SI: LP alpha_z(0, 90) = 0.254 N/cm^3
    lp = LiTreersRFT(coefficients='poppy_lp')
    assert lp.zeta == 1e6 and lp.penetration == pytest.approx(0.254e6)
    np.testing.assert_allclose(stress((0, 0, -1), (0, 0, -1), lp), [0, 0, 0.254e6], atol=1e-6)
    # horizontal drag: -alpha_x(0, 0) = -(C11+C01+C-11) and alpha_z(0, 0) = A00+A10, N/m^3
    np.testing.assert_allclose(stress((0, 0, -1), (1, 0, 0), lp) / 1e6,
                               [-0.031, 0, 0.051 + 0.047], atol=1e-12)
    assert lp.alpha1 == pytest.approx(0.031e6)
    # the media presets pass zeta = 1e6 explicitly (rft/media.py): same model
    explicit = LiTreersRFT(zeta=1e6, coefficients='poppy_lp')
    assert explicit.penetration == pytest.approx(0.254e6)
    assert LiTreersRFT(coefficients='poppy_cp').penetration == pytest.approx(0.464e6)
    # another zeta scales the set by zeta / 1e6
    doubled = LiTreersRFT(2e6, coefficients='poppy_cp')
    np.testing.assert_allclose(stress((0, 0, -1), (0, 0, -1), doubled), [0, 0, 0.928e6])


@pytest.mark.parametrize('kwargs', [{}, {'zeta': 0.0}, {'zeta': float('nan')},
                                    {'zeta': -1.0}, {'zeta': 1.0, 'coefficients': 'clay'},
                                    {'zeta': 1.0, 'alpha1_ratio': -0.1},
                                    {'zeta': 1.0, 'flat_tol': 1.0}])
def test_invalid_parameters(kwargs):
    with pytest.raises(ValueError):
        LiTreersRFT(**kwargs)
