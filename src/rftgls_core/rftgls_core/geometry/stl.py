"""STL files <-> TriMesh: binary and ASCII reader/writer, vertex welding, unit conversion.

STL stores a triangle soup in whatever length unit the CAD tool used (usually mm). Inside the
library everything is in metres, so the unit is an explicit argument at this edge and the
conversion happens here, once. The per-facet normals stored in the file are ignored: the
vertex winding is the only orientation the rest of the library trusts (see geometry/validate.py
to make it consistent and outward).

Every failure to read a file is a MeshError (a ValueError) with a one-line message naming the
file and the problem, never a raw struct/numpy/unicode traceback.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

from rftgls_conventions.safe_read import InputFileError, read_bytes
from rftgls_conventions.safe_write import write_bytes

from .mesh import TriMesh

# Metres per file unit.
UNIT_SCALE: dict[str, float] = {'mm': 1e-3, 'cm': 1e-2, 'm': 1.0}

# Vertices closer than this fraction of the bounding-box diagonal are one vertex. float32
# coordinates (binary STL) carry ~6e-8 relative noise; 1e-6 absorbs that and stays far below
# any real feature of a leg mesh.
WELD_RTOL = 1e-6
# ... but never more than this fraction of the median edge (the mesh's feature size): one
# stray triangle far away inflates the bounding box, and a box-relative tolerance would then
# weld every real vertex into one point and the whole mesh into nothing.
WELD_FEATURE_RTOL = 1e-3
# A leg or body mesh needs ~1e2..1e4 facets; beyond this a file is a scan or a mistake, and
# RFT on it would only exhaust memory.
# The file size is bounded before reading (safe_read.MAX_BYTES['mesh']: 1e6 ASCII triangles).
MAX_TRIANGLES = 1_000_000

_HEADER_BYTES = 80
_RECORD = np.dtype([('normal', '<f4', (3,)), ('vertices', '<f4', (3, 3)), ('attr', '<u2')])
assert _RECORD.itemsize == 50

_FLOAT = r'([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[-+]?(?:nan|inf)\w*)'
_VERTEX_RE = re.compile(rb'\bvertex\s+' + (_FLOAT + r'\s+').encode() * 2 + _FLOAT.encode(),
                        re.IGNORECASE)
_WORD_RE = {w: re.compile(rb'\b' + w.encode() + rb'\b', re.IGNORECASE)
            for w in ('facet', 'endfacet', 'vertex', 'endsolid')}


class MeshError(ValueError):
    """A mesh file or mesh that cannot be used (unreadable, malformed, empty, non-finite)."""


def _scale(units: str) -> float:
    try:
        return UNIT_SCALE[units]
    except KeyError:
        raise ValueError(f'units must be one of {sorted(UNIT_SCALE)}, got {units!r}') from None


# ----------------------------------------------------------------------------------- welding

def weld_triangles(triangles: np.ndarray, rtol: float = WELD_RTOL) -> TriMesh:
    """Indexed mesh from a triangle soup (F, 3, 3), merging vertices closer than
    min(rtol * diag, WELD_FEATURE_RTOL * median edge length).

    diag is the bounding-box diagonal, so the tolerance scales with the mesh and does not
    depend on the unit; the median-edge cap keeps a far-away stray facet from inflating it.
    Exact duplicates (the common case) are merged by np.unique; near duplicates by a k-d tree
    on the unique points, grouped transitively.
    """
    tri = np.asarray(triangles, dtype=float)
    if tri.ndim != 3 or tri.shape[1:] != (3, 3):
        raise ValueError(f'triangles must have shape (F, 3, 3), got {tri.shape}')
    corners = tri.reshape(-1, 3)
    if len(corners) == 0:
        return TriMesh(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64))
    uniq, inverse = np.unique(corners, axis=0, return_inverse=True)
    inverse = inverse.reshape(-1)
    diag = float(np.linalg.norm(uniq.max(axis=0) - uniq.min(axis=0)))
    edges = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2)
    feature = float(np.median(edges[edges > 0.0])) if np.any(edges > 0.0) else 0.0
    tol = min(rtol * diag, WELD_FEATURE_RTOL * feature)
    if tol > 0.0 and len(uniq) > 1:
        pairs = cKDTree(uniq).query_pairs(tol, output_type='ndarray')
        if len(pairs):
            n = len(uniq)
            graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
            _, label = connected_components(graph, directed=False)
            # Representative of each group: its first (lexicographically smallest) point.
            first = np.full(label.max() + 1, n, dtype=np.int64)
            np.minimum.at(first, label, np.arange(n))
            uniq, inverse = uniq[first], label[inverse]
    return TriMesh(uniq, inverse.reshape(-1, 3))


# ----------------------------------------------------------------------------------- reading

def read_stl(path: str | os.PathLike, units: str = 'mm', weld_rtol: float = WELD_RTOL) -> TriMesh:
    """Read a binary or ASCII STL file into a welded TriMesh in metres.

    units: the length unit of the numbers in the file ('mm', 'cm' or 'm').
    Raises MeshError when the file is missing, empty, truncated, malformed, holds non-finite
    coordinates or no triangles. Orientation is the file's vertex winding, unchecked.
    """
    scale = _scale(units)
    path = Path(path)
    try:
        data = read_bytes(path, 'mesh', 'STL mesh')
    except InputFileError as exc:
        raise MeshError(str(exc)) from None
    if not data:
        raise MeshError(f'{path}: empty file, not an STL')
    tri = _parse_stl(data, path)
    if len(tri) > MAX_TRIANGLES:
        raise MeshError(f'{path}: {len(tri)} triangles, more than the {MAX_TRIANGLES} this '
                        'tool accepts (simplify the mesh)')
    if len(tri) == 0:
        raise MeshError(f'{path}: STL file contains zero triangles')
    if not np.all(np.isfinite(tri)):
        bad = int(np.count_nonzero(~np.all(np.isfinite(tri), axis=(1, 2))))
        raise MeshError(f'{path}: {bad} triangle(s) have NaN or infinite coordinates')
    return weld_triangles(tri * scale, weld_rtol)


def _parse_stl(data: bytes, path: Path) -> np.ndarray:
    """Triangle corners (F, 3, 3) in file units, choosing binary or ASCII reliably."""
    size = len(data)
    n_bin = int(np.frombuffer(data, '<u4', 1, _HEADER_BYTES)[0]) if size >= 84 else -1
    binary_size_ok = n_bin >= 0 and size == 84 + 50 * n_bin
    looks_ascii = data.lstrip()[:5].lower() == b'solid'
    # Some binary exporters start the 80-byte header with "solid" too; the size formula
    # decides. An ASCII file that happens to satisfy it is still ASCII if it parses as text
    # and ends with "endsolid".
    if binary_size_ok and not (looks_ascii and _is_plain_ascii_stl(data)):
        records = np.frombuffer(data, _RECORD, n_bin, 84)
        return records['vertices'].astype(float)
    if looks_ascii:
        return _parse_ascii(data, path)
    if size < 84:
        raise MeshError(f'{path}: {size} bytes is too short for a binary STL (84-byte minimum) '
                        f'and it does not start with "solid"')
    raise MeshError(f'{path}: truncated or corrupt binary STL: header announces {n_bin} '
                    f'triangles ({84 + 50 * n_bin} bytes) but the file has {size} bytes')


def _is_plain_ascii_stl(data: bytes) -> bool:
    try:
        data.decode('ascii')
    except UnicodeDecodeError:
        return False
    return _WORD_RE['endsolid'].search(data[-256:]) is not None


def _parse_ascii(data: bytes, path: Path) -> np.ndarray:
    try:
        data.decode('ascii')
    except UnicodeDecodeError as exc:
        raise MeshError(f'{path}: starts with "solid" but is neither ASCII STL nor a valid '
                        f'binary STL (non-ASCII byte at offset {exc.start})') from None
    counts = {w: len(rx.findall(data)) for w, rx in _WORD_RE.items()}
    if counts['endsolid'] == 0:
        raise MeshError(f'{path}: malformed ASCII STL: no "endsolid" (file truncated?)')
    # "facet" also matches inside "endfacet" only with a word boundary before it, which
    # "endfacet" lacks, so the two counts are independent.
    n_facet, n_end = counts['facet'], counts['endfacet']
    found = _VERTEX_RE.findall(data)
    if n_facet != n_end:
        raise MeshError(f'{path}: malformed ASCII STL: {n_facet} "facet" but {n_end} "endfacet"')
    if len(found) != counts['vertex']:
        raise MeshError(f'{path}: malformed ASCII STL: {counts["vertex"] - len(found)} '
                        f'"vertex" line(s) without three numbers')
    if len(found) != 3 * n_facet:
        raise MeshError(f'{path}: malformed ASCII STL: {len(found)} vertices for {n_facet} '
                        f'facets (expected 3 per facet)')
    try:
        xyz = np.array(found, dtype=float) if found else np.zeros((0, 3))
    except ValueError:
        raise MeshError(f'{path}: malformed ASCII STL: unparsable vertex coordinate') from None
    return xyz.reshape(-1, 3, 3)


# ----------------------------------------------------------------------------------- writing

def write_stl(path: str | os.PathLike, mesh: TriMesh, units: str = 'mm', ascii: bool = False,
              name: str = 'rftgls') -> None:
    """Write mesh (metres) to an STL file whose numbers are in `units`.

    Facet normals are computed from the winding (zero for degenerate facets). The binary
    header never starts with "solid", so readers cannot mistake it for ASCII.
    """
    scale = _scale(units)
    if len(mesh.faces) == 0:
        raise MeshError(f'{path}: refusing to write an STL with zero triangles')
    tri = mesh.triangles / scale
    normals = mesh.facets().normals
    if not np.all(np.isfinite(tri)):
        raise MeshError(f'{path}: mesh has NaN or infinite coordinates')
    path = Path(path)
    if ascii:
        label = re.sub(r'\s+', '_', name) or 'rftgls'
        block = ('facet normal %.9e %.9e %.9e\n  outer loop\n'
                 + '    vertex %.17g %.17g %.17g\n' * 3 + '  endloop\nendfacet\n')
        rows = np.concatenate([normals, tri.reshape(-1, 9)], axis=1)
        body = (block * len(rows)) % tuple(rows.ravel().tolist())
        write_bytes(path, f'solid {label}\n{body}endsolid {label}\n'.encode('ascii'))
        return
    header = f'RFT-GLS binary STL, units={units}, name={name}'.encode('ascii', 'replace')
    records = np.zeros(len(tri), dtype=_RECORD)
    records['normal'] = normals
    records['vertices'] = tri
    write_bytes(path, header[:_HEADER_BYTES].ljust(_HEADER_BYTES, b' ')
                + np.uint32(len(tri)).astype('<u4').tobytes() + records.tobytes())
