"""Parametric shapes: closed, outward, and converging to their analytic volume and area."""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

from rftgls_core.geometry.shapes import (
    annular_sector_volume,
    box,
    c_leg,
    ellipsoid,
    icosphere,
    plate,
)
from rftgls_core.geometry.validate import (
    clean_mesh,
    euler_characteristic,
    is_closed,
    is_consistently_oriented,
    surface_area,
)

SHAPES = {
    'c_leg_default': lambda: c_leg(),
    'c_leg_partial_fine': lambda: c_leg(0.06, 0.004, 0.012, n_arc=7, arc_angle=2.0,
                                        n_thick=2, n_width=3),
    'icosphere0': lambda: icosphere(0.3, 0),
    'icosphere3': lambda: icosphere(0.01, 3),
    'ellipsoid': lambda: ellipsoid(0.02, 0.01, 0.005, 2),
    'box': lambda: box(0.1, 0.2, 0.3),
    'box_grid': lambda: box(0.1, 0.2, 0.3, (2, 3, 4)),
    'plate': lambda: plate(0.04, 0.02, 0.002, subdivisions=8),
}


@pytest.mark.parametrize('name', sorted(SHAPES))
def test_shape_is_closed_and_outward(name):
    mesh = SHAPES[name]()
    assert is_closed(mesh)                         # every edge shared by exactly two faces
    assert euler_characteristic(mesh) == 2         # one genus-0 shell
    assert is_consistently_oriented(mesh)
    assert mesh.signed_volume() > 0
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        _, report = clean_mesh(mesh)
    assert report.flipped == 0 and report.outward_proven and report.dropped_degenerate == 0


@pytest.mark.parametrize('n_arc', [6, 24, 96])
def test_c_leg_volume_and_area(n_arc):
    d, th, w, ang = 0.090, 0.005, 0.010, math.pi
    leg = c_leg(d, th, w, n_arc=n_arc, arc_angle=ang)
    # chords: the polygonal annular sector is exact to round-off ...
    assert leg.signed_volume() == pytest.approx(annular_sector_volume(d, th, w, ang, n_arc),
                                                rel=1e-12)
    # ... and the exact annular sector (arc_angle/2) (ro^2 - ri^2) w = arc_angle R th w is
    # approached with relative error 1 - sin(x)/x ~ x^2 / 6, x = arc_angle / n_arc
    exact = 0.5 * ang * ((d / 2 + th / 2) ** 2 - (d / 2 - th / 2) ** 2) * w
    assert exact == pytest.approx(ang * d / 2 * th * w, rel=1e-12)
    x = ang / n_arc
    assert abs(leg.signed_volume() / exact - 1) <= x * x / 6 * 1.01
    ro, ri = d / 2 + th / 2, d / 2 - th / 2
    area = 2 * exact / w + ang * (ro + ri) * w + 2 * th * w
    assert abs(surface_area(leg) / area - 1) <= x * x / 6 * 1.01


def test_c_leg_frame():
    d, th, w = 0.090, 0.005, 0.010
    leg = c_leg(d, th, w, n_arc=24)
    v = leg.vertices
    hip = np.abs(v[:, 0]) < 1e-15                     # t = 0 and t = pi ends lie on x = 0
    assert np.all(v[:, 0] >= -1e-15)                  # bulges toward +x
    assert v[:, 0].max() == pytest.approx(d / 2 + th / 2)
    assert v[:, 2].max() == pytest.approx(th / 2)     # hip cross-section centred on origin
    assert v[:, 2].min() == pytest.approx(-d - th / 2)  # toe at (0, 0, -arc_diameter)
    assert np.sort(np.unique(v[hip, 2])) == pytest.approx([-d - th / 2, -d + th / 2,
                                                          -th / 2, th / 2])
    assert v[:, 1].min() == pytest.approx(-w / 2) and v[:, 1].max() == pytest.approx(w / 2)
    assert len(leg.faces) == 8 * 24 + 4
    # partial arc: the toe is on the centreline circle at t = arc_angle
    quarter = c_leg(d, th, w, n_arc=8, arc_angle=math.pi / 2).vertices
    toe = quarter[np.isclose(quarter[:, 2], -d / 2)]
    assert toe[:, 0] == pytest.approx(np.where(toe[:, 0] > d / 2, d / 2 + th / 2,
                                               d / 2 - th / 2))


def test_icosphere_converges():
    r = 0.01
    errors = []
    for s in range(5):
        sphere = icosphere(r, s)
        assert len(sphere.faces) == 20 * 4 ** s
        np.testing.assert_allclose(np.linalg.norm(sphere.vertices, axis=1), r, rtol=1e-14)
        errors.append(1 - sphere.signed_volume() / (4 / 3 * math.pi * r ** 3))
        assert 0 < 1 - surface_area(sphere) / (4 * math.pi * r * r) < 2 * errors[-1]
    assert all(0 < b < a / 3 for a, b in zip(errors, errors[1:]))   # ~4x per level
    assert errors[-1] < 2.5e-3                                     # 5120 facets


def test_ellipsoid():
    a, b, c = 0.03, 0.02, 0.01
    e = ellipsoid(a, b, c, 4)
    v = e.vertices
    np.testing.assert_allclose((v[:, 0] / a) ** 2 + (v[:, 1] / b) ** 2 + (v[:, 2] / c) ** 2,
                               1.0, rtol=1e-13)
    assert e.signed_volume() == pytest.approx(4 / 3 * math.pi * a * b * c, rel=2.5e-3)


def test_box_and_plate_are_exact():
    b = box(0.1, 0.2, 0.3, (2, 3, 4))
    assert b.signed_volume() == pytest.approx(0.006, rel=1e-12)
    assert surface_area(b) == pytest.approx(2 * (0.02 + 0.06 + 0.03), rel=1e-12)
    assert len(b.faces) == 2 * 2 * (2 * 3 + 3 * 4 + 4 * 2)
    np.testing.assert_allclose(b.vertices.min(axis=0), [-0.05, -0.1, -0.15])
    p = plate(0.04, 0.02, 0.002, subdivisions=8)
    assert p.signed_volume() == pytest.approx(0.04 * 0.02 * 0.002, rel=1e-12)
    # int subdivisions: cells along the longest side, near-square cells elsewhere
    edges = np.linalg.norm(p.triangles - np.roll(p.triangles, 1, axis=1), axis=2)
    assert edges.max() <= math.hypot(0.005, 0.005) + 1e-15


@pytest.mark.parametrize('call', [
    lambda: c_leg(thickness=0.1), lambda: c_leg(arc_angle=7.0), lambda: c_leg(width=-1),
    lambda: c_leg(n_arc=0), lambda: box(1, 0, 1), lambda: box(1, 1, 1, 0),
    lambda: icosphere(float('nan')), lambda: icosphere(1, -1), lambda: ellipsoid(1, 1, 0)])
def test_invalid_parameters(call):
    with pytest.raises(ValueError):
        call()
