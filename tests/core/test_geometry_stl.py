"""STL reader/writer: round trips, units, vertex welding, and a clear MeshError per bad file."""
from __future__ import annotations

import struct

import numpy as np
import pytest
from scipy.spatial import cKDTree

from rftgls_core.geometry.mesh import TriMesh
from rftgls_core.geometry.shapes import c_leg, icosphere
from rftgls_core.geometry.stl import MeshError, read_stl, weld_triangles, write_stl
from rftgls_core.geometry.validate import is_closed, is_consistently_oriented

BOX_TRI = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]]], dtype=float)


def _same_surface(a: TriMesh, b: TriMesh, tol: float) -> None:
    """Same triangles (by centroid) with the same outward normals, whatever the vertex order."""
    fa, fb = a.facets(), b.facets()
    assert len(fa) == len(fb)
    dist, idx = cKDTree(fb.centroids).query(fa.centroids)
    assert dist.max() < tol
    assert np.all(np.einsum('ij,ij->i', fa.normals, fb.normals[idx]) > 1 - 1e-6)
    assert len(a.vertices) == len(b.vertices)


@pytest.mark.parametrize('ascii', [False, True])
@pytest.mark.parametrize('units', ['mm', 'm'])
def test_round_trip(tmp_path, ascii, units):
    leg = c_leg(n_arc=12)
    path = tmp_path / f'leg_{units}_{ascii}.stl'
    write_stl(path, leg, units=units, ascii=ascii)
    back = read_stl(path, units=units)
    # binary stores float32: about 1e-7 relative of a ~0.1 m coordinate (in either unit)
    _same_surface(leg, back, tol=1e-12 if ascii else 1e-8)
    assert is_closed(back) and is_consistently_oriented(back)
    assert back.signed_volume() == pytest.approx(leg.signed_volume(), rel=1e-6)


def test_units_scale_the_numbers(tmp_path):
    sphere = icosphere(0.02, 1)
    write_stl(tmp_path / 's.stl', sphere, units='mm')
    first = np.frombuffer((tmp_path / 's.stl').read_bytes(), '<f4', 9, 84 + 12).reshape(3, 3)
    np.testing.assert_allclose(np.linalg.norm(first, axis=1), 20.0, rtol=1e-6)  # numbers in mm
    as_mm = read_stl(tmp_path / 's.stl', units='mm')
    as_m = read_stl(tmp_path / 's.stl', units='m')
    np.testing.assert_allclose(as_m.vertices, 1000.0 * as_mm.vertices, rtol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(as_mm.vertices, axis=1), 0.02, rtol=1e-6)


def test_binary_header_starting_with_solid_is_read_as_binary(tmp_path):
    path = tmp_path / 'solid_header.stl'
    write_stl(path, icosphere(1.0, 1), units='m')
    data = bytearray(path.read_bytes())
    data[:80] = b'solid exported by a CAD tool'.ljust(80)
    path.write_bytes(bytes(data))
    assert len(read_stl(path, units='m').faces) == 80


def test_ascii_with_irregular_whitespace_and_case(tmp_path):
    path = tmp_path / 'messy.stl'
    path.write_text('  solid messy\nFACET NORMAL 0 0 1\n outer loop\n\tvertex 0 0 0\n'
                    'vertex 1.0e0 0 0\n  vertex 0 +1 .0\n endloop\n ENDFACET\nendsolid\n')
    mesh = read_stl(path, units='m')
    np.testing.assert_allclose(mesh.triangles[0][np.argsort(mesh.faces[0])],
                               mesh.vertices[np.sort(mesh.faces[0])])
    assert mesh.facets().normals[0] == pytest.approx([0, 0, 1])


def test_welding_merges_near_duplicates_relative_to_size():
    sphere = icosphere(1.0, 2)
    soup = sphere.triangles + np.random.default_rng(0).normal(0, 1e-9, sphere.triangles.shape)
    welded = weld_triangles(soup)
    assert len(welded.vertices) == len(sphere.vertices)
    assert is_closed(welded)
    # the same soup scaled to mm welds the same way (tolerance relative to the bounding box)
    assert len(weld_triangles(soup * 1e-3).vertices) == len(sphere.vertices)


def test_rejects_unknown_units(tmp_path):
    with pytest.raises(ValueError, match='units'):
        read_stl(tmp_path / 'x.stl', units='inch')


def test_refuses_to_write_empty_mesh(tmp_path):
    with pytest.raises(MeshError, match='zero triangles'):
        write_stl(tmp_path / 'e.stl', TriMesh(np.zeros((0, 3)), np.zeros((0, 3), int)))


def _binary(tri: np.ndarray, count: int | None = None) -> bytes:
    body = b''.join(struct.pack('<12fH', 0, 0, 0, *t.ravel(), 0) for t in tri)
    return b'\0' * 80 + struct.pack('<I', len(tri) if count is None else count) + body


_GOOD_ASCII = ('solid t\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n'
               'vertex 0 1 0\nendloop\nendfacet\nendsolid t\n')

BAD_FILES = {
    'empty': (b'', 'empty file'),
    'short_garbage': (b'hello world', 'too short'),
    'truncated_binary': (_binary(np.repeat(BOX_TRI, 4, 0))[:-30], 'truncated'),
    'binary_count_too_large': (_binary(BOX_TRI, count=7), 'announces 7 triangles'),
    'binary_zero_triangles': (_binary(BOX_TRI[:0]), 'zero triangles'),
    'binary_nan': (_binary(np.array([[[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]])), 'NaN'),
    'ascii_truncated': (_GOOD_ASCII[:70].encode(), 'endsolid'),
    'ascii_bad_number': (_GOOD_ASCII.replace('vertex 1 0 0', 'vertex 1 zero 0').encode(),
                         'without three numbers'),
    'ascii_missing_vertex': (_GOOD_ASCII.replace('vertex 0 1 0\n', '').encode(),
                             'expected 3 per facet'),
    'ascii_unbalanced_facets': (_GOOD_ASCII.replace('endfacet\n', '').encode(), '"endfacet"'),
    'ascii_nan': (_GOOD_ASCII.replace('vertex 1 0 0', 'vertex nan 0 0').encode(), 'NaN'),
    'ascii_zero_triangles': (b'solid t\nendsolid t\n', 'zero triangles'),
    'ascii_not_text': (b'solid \xff\xfe' + b'\x01' * 40, 'neither ASCII STL nor'),
}


@pytest.mark.parametrize('case', sorted(BAD_FILES))
def test_malformed_files_raise_mesh_error(tmp_path, case):
    data, expected = BAD_FILES[case]
    path = tmp_path / f'{case}.stl'
    path.write_bytes(data)
    with pytest.raises(MeshError) as info:
        read_stl(path)
    message = str(info.value)
    assert isinstance(info.value, ValueError)
    assert path.name in message and expected in message
    assert '\n' not in message


def test_missing_file_raises_mesh_error(tmp_path):
    with pytest.raises(MeshError, match='nope.stl: cannot read'):
        read_stl(tmp_path / 'nope.stl')


def test_one_stray_far_triangle_does_not_weld_the_mesh_away():
    """A bounding-box-relative tolerance would let one far triangle merge every real vertex:
    the tolerance is capped by the feature size, and clean_mesh refuses strays."""
    from rftgls_core.geometry.validate import clean_mesh
    leg = c_leg(arc_diameter=0.09, thickness=0.005, width=0.01, n_arc=12)
    far = np.array([[[1e5, 1e5, 1e5], [1e5 + 0.01, 1e5, 1e5], [1e5, 1e5 + 0.01, 1e5]]])
    welded = weld_triangles(np.concatenate([leg.triangles, far]))
    assert len(welded.vertices) == len(leg.vertices) + 3
    assert len(welded.faces) == len(leg.faces) + 1
    with pytest.raises(MeshError, match='stray'):
        clean_mesh(welded)
    # the leg alone is untouched
    clean, report = clean_mesh(weld_triangles(leg.triangles))
    assert len(clean.faces) == len(leg.faces) and report.outward_proven


def test_too_many_triangles_is_refused(tmp_path, monkeypatch):
    from rftgls_core.geometry import stl
    monkeypatch.setattr(stl, 'MAX_TRIANGLES', 10)
    path = tmp_path / 'big.stl'
    write_stl(path, icosphere(0.01, 1), units='m')       # 80 triangles
    with pytest.raises(MeshError, match='more than the 10'):
        read_stl(path, units='m')
