"""clean_mesh: degenerate facets dropped with a warning, windings made consistent and outward."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from rftgls_core.geometry.mesh import TriMesh
from rftgls_core.geometry.shapes import box, icosphere
from rftgls_core.geometry.stl import MeshError
from rftgls_core.geometry.validate import (
    MeshWarning,
    clean_mesh,
    euler_characteristic,
    is_closed,
    is_consistently_oriented,
)

SPHERE = icosphere(1.0, 2)


def _flip(mesh: TriMesh, mask: np.ndarray) -> TriMesh:
    return TriMesh(mesh.vertices, np.where(mask[:, None], mesh.faces[:, ::-1], mesh.faces))


def _clean_quiet(mesh: TriMesh):
    with warnings.catch_warnings():
        warnings.simplefilter('error')          # a clean closed mesh raises no warning
        return clean_mesh(mesh)


def _interior_edges_once_each_way(mesh: TriMesh) -> bool:
    directed = mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    fwd = {tuple(e) for e in directed.tolist()}
    return len(fwd) == len(directed) and all((b, a) in fwd for a, b in fwd)


def test_clean_closed_mesh_is_unchanged():
    cleaned, report = _clean_quiet(SPHERE)
    assert report.flipped == 0 and report.outward_proven and report.components == 1
    np.testing.assert_allclose(cleaned.facets().normals, SPHERE.facets().normals)


def test_partly_flipped_mesh_is_repaired():
    mask = np.random.default_rng(1).random(len(SPHERE.faces)) < 0.3
    cleaned, report = _clean_quiet(_flip(SPHERE, mask))
    assert report.flipped == mask.sum()
    assert cleaned.signed_volume() == pytest.approx(SPHERE.signed_volume(), rel=1e-12)
    assert cleaned.signed_volume() > 0
    assert _interior_edges_once_each_way(cleaned)
    np.testing.assert_allclose(cleaned.facets().normals, SPHERE.facets().normals, atol=1e-12)


def test_fully_inverted_mesh_is_turned_outward():
    cleaned, report = _clean_quiet(SPHERE.flipped())
    assert report.flipped == len(SPHERE.faces)
    assert cleaned.signed_volume() > 0


@settings(max_examples=25, deadline=None)
@given(st.lists(st.booleans(), min_size=80, max_size=80))
def test_any_flip_pattern_is_repaired(flags):
    sphere = icosphere(1.0, 1)
    cleaned, _ = _clean_quiet(_flip(sphere, np.array(flags)))
    np.testing.assert_allclose(cleaned.facets().normals, sphere.facets().normals, atol=1e-12)


def test_components_are_oriented_independently():
    other = icosphere(0.5, 1).transformed(np.eye(3), [5.0, 0.0, 0.0]).flipped()
    cleaned, report = _clean_quiet(TriMesh.concatenate([box(1, 1, 1, 2), other]))
    assert report.components == 2 and report.closed_components == 2
    assert report.flipped == len(other.faces)
    assert cleaned.signed_volume() == pytest.approx(1.0 + other.flipped().signed_volume())


def test_degenerate_facets_are_dropped_with_a_warning():
    cube = box(1, 1, 1)
    v = np.vstack([cube.vertices, 0.5 * (cube.vertices[0] + cube.vertices[1])])
    mid = len(v) - 1
    extra = np.array([[0, mid, 1],            # zero area: three collinear points
                      [2, 2, 3]])             # repeated vertex index
    dirty = TriMesh(v, np.vstack([cube.faces, extra]))
    with pytest.warns(MeshWarning, match='dropped 2 degenerate'):
        cleaned, report = clean_mesh(dirty)
    assert report.dropped_degenerate == 2 and report.faces_in == 14
    assert len(cleaned.faces) == 12 and len(cleaned.vertices) == 8   # unused vertex removed
    assert report.outward_proven


def test_near_zero_area_is_relative_to_mesh_size():
    for scale in (1e-3, 1.0, 1e3):
        tri = np.array([[0, 0, 0], [1, 0, 0], [0.5, 1e-12, 0], [0, 1, 0]]) * scale
        with pytest.warns(MeshWarning):
            _, report = clean_mesh(TriMesh(tri, [[0, 1, 2], [0, 1, 3]]))
        assert report.dropped_degenerate == 1


def test_duplicate_facets_are_dropped():
    cube = box(1, 1, 1)
    with pytest.warns(MeshWarning, match='duplicate'):
        cleaned, report = clean_mesh(TriMesh(cube.vertices, np.vstack([cube.faces,
                                                                       cube.faces[:2]])))
    assert report.dropped_duplicate == 2 and report.outward_proven


def test_open_mesh_is_made_consistent_but_not_proven_outward():
    cube = box(1, 1, 1, 3)
    top = cube.facets().centroids[:, 2] > 0.49
    open_box = TriMesh(cube.vertices, cube.faces[~top])
    mask = np.zeros(len(open_box.faces), bool)
    mask[::5] = True
    with pytest.warns(MeshWarning, match='not proven'):
        cleaned, report = clean_mesh(_flip(open_box, mask))
    assert not report.closed and not report.outward_proven
    assert report.flipped == mask.sum()          # the majority orientation is kept
    assert is_consistently_oriented(cleaned)
    assert not is_closed(cleaned)


def test_non_manifold_and_non_orientable_are_reported():
    fin = TriMesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1.0]]),
                  [[0, 1, 2], [1, 0, 3], [0, 1, 4]])
    with pytest.warns(MeshWarning):
        _, report = clean_mesh(fin)
    assert report.non_manifold_edges == 1
    # Moebius strip: no consistent winding exists
    n = 12
    t = np.linspace(0, 2 * np.pi, n, endpoint=False)
    ring = []
    for s in (-0.2, 0.2):
        ring.append(np.stack([(1 + s * np.cos(t / 2)) * np.cos(t),
                              (1 + s * np.cos(t / 2)) * np.sin(t), s * np.sin(t / 2)], 1))
    v = np.concatenate(ring)                    # a_i = i, b_i = n + i
    faces = []
    for i in range(n - 1):
        faces += [[i, i + 1, n + i + 1], [i, n + i + 1, n + i]]
    faces += [[n - 1, n, 0], [n - 1, 0, 2 * n - 1]]     # the half twist joins a to b
    with pytest.warns(MeshWarning):
        _, report = clean_mesh(TriMesh(v, faces))
    assert report.inconsistent_edges >= 1 and not report.outward_proven


def test_all_degenerate_raises():
    with pytest.warns(MeshWarning), pytest.raises(MeshError, match='no usable facet'):
        clean_mesh(TriMesh(np.zeros((3, 3)), [[0, 1, 2]]))


def test_topology_helpers():
    assert is_closed(SPHERE) and euler_characteristic(SPHERE) == 2
    assert is_consistently_oriented(SPHERE)
    assert not is_consistently_oriented(_flip(SPHERE, np.arange(len(SPHERE.faces)) == 0))
