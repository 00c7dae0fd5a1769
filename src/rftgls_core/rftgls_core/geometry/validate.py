"""Mesh hygiene before RFT: drop degenerate facets, make the winding consistent and outward.

RFT reads the facet normal from the vertex winding (geometry/mesh.py), and the engine keeps a
facet only when it leads (n . v > 0). A single inward-wound facet therefore swaps leading and
trailing for that facet and silently corrupts the force, so meshes from files go through
clean_mesh once, at load time.

Orientation works per connected component (faces joined through manifold edges, i.e. edges
shared by exactly two faces):
1. propagate a consistent winding over a spanning tree of the face-adjacency graph (BFS), so
   that every shared edge is traversed once in each direction;
2. a closed component is then flipped as a whole if its signed volume is negative;
3. an open component has no inside: it keeps the orientation most of its input faces had, and
   the report says outwardness is not proven.

All of it is vectorised over faces (sparse graphs from scipy, pointer jumping for the parity
along the BFS tree); there is no Python loop over facets.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import breadth_first_order, connected_components

from .mesh import TriMesh
from .stl import MeshError

# A facet whose height (2 * area / longest edge) is below this fraction of the bounding-box
# diagonal is degenerate: its normal is numerical noise.
DEGENERATE_RTOL = 1e-9
# A component farther from the largest one than this many times the largest one's size is a
# stray facet of a CAD export, not part of the body: RFT would put a buried lever arm of that
# length into the moment, so the mesh is refused rather than silently used.
STRAY_FACTOR = 100.0


class MeshWarning(UserWarning):
    """Something in a mesh was repaired or could not be proven (degenerate facets, open shell)."""


@dataclass(frozen=True)
class CleanReport:
    """What clean_mesh changed and what it could establish about the mesh."""

    faces_in: int
    dropped_degenerate: int      # zero / near-zero area, or repeated vertex index
    dropped_duplicate: int       # same three vertices as an earlier facet
    components: int              # connected through manifold edges
    closed_components: int       # every edge shared by exactly two facets
    non_manifold_edges: int      # edges shared by three or more facets
    inconsistent_edges: int      # still traversed twice the same way (non-orientable)
    flipped: int                 # facets whose winding was reversed

    @property
    def closed(self) -> bool:
        return self.components > 0 and self.closed_components == self.components

    @property
    def outward_proven(self) -> bool:
        """True when every component is a closed, consistently wound shell (volume > 0)."""
        return self.closed and self.non_manifold_edges == 0 and self.inconsistent_edges == 0


# ------------------------------------------------------------------------------ edge topology

@dataclass(frozen=True)
class _Edges:
    directed: np.ndarray    # (3F, 2) vertex pairs; face k owns rows 3k, 3k+1, 3k+2
    inverse: np.ndarray     # (3F,) index of the undirected edge of each directed edge
    counts: np.ndarray      # (E,) number of faces using each undirected edge


def _edges(faces: np.ndarray) -> _Edges:
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    _, inverse, counts = np.unique(np.sort(directed, axis=1), axis=0, return_inverse=True,
                                   return_counts=True)
    return _Edges(directed, inverse.reshape(-1), counts)


def is_closed(mesh: TriMesh) -> bool:
    """Every edge is shared by exactly two facets (a watertight 2-manifold edge structure)."""
    return len(mesh.faces) > 0 and bool(np.all(_edges(mesh.faces).counts == 2))


def is_consistently_oriented(mesh: TriMesh) -> bool:
    """No directed edge is used twice: shared edges are traversed once in each direction."""
    directed = mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    return len(np.unique(directed, axis=0)) == len(directed)


def euler_characteristic(mesh: TriMesh) -> int:
    """V - E + F over the vertices the faces use (2 for a closed genus-0 surface)."""
    used = len(np.unique(mesh.faces))
    return int(used - len(_edges(mesh.faces).counts) + len(mesh.faces))


def surface_area(mesh: TriMesh) -> float:
    """Total area in m^2."""
    return float(mesh.facets().areas.sum())


# ------------------------------------------------------------------------------- clean_mesh

def clean_mesh(mesh: TriMesh, degenerate_rtol: float = DEGENERATE_RTOL
               ) -> tuple[TriMesh, CleanReport]:
    """Drop degenerate and duplicate facets, orient every component consistently and outward.

    Returns the cleaned mesh (unused vertices removed) and a CleanReport. Warns (MeshWarning)
    when facets are dropped and when outwardness cannot be proven. Raises MeshError when no
    usable facet is left.
    """
    faces = mesh.faces
    faces_in = len(faces)
    faces, n_degenerate = _drop_degenerate(mesh.vertices, faces, degenerate_rtol)
    if n_degenerate:
        warnings.warn(f'clean_mesh: dropped {n_degenerate} degenerate facet(s) (zero or '
                      f'near-zero area, or repeated vertex) of {faces_in}', MeshWarning,
                      stacklevel=2)
    _, first = np.unique(np.sort(faces, axis=1), axis=0, return_index=True)
    n_duplicate = len(faces) - len(first)
    if n_duplicate:
        faces = faces[np.sort(first)]
        warnings.warn(f'clean_mesh: dropped {n_duplicate} duplicate facet(s)', MeshWarning,
                      stacklevel=2)
    if len(faces) == 0:
        raise MeshError(f'mesh has no usable facet ({faces_in} in, all degenerate)')
    used, compact = np.unique(faces, return_inverse=True)
    vertices, faces = mesh.vertices[used], compact.reshape(-1, 3)

    edges = _edges(faces)
    labels, n_comp, flip = _consistent_winding(faces, edges)
    _refuse_strays(vertices, faces, labels, n_comp)
    closed_comp = _closed_components(edges, labels, n_comp)
    # Signed volume per component about the bounding-box centre (smaller round-off than the
    # origin for meshes far from it).
    tri = vertices[faces] - 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    vol = np.einsum('ij,ij->i', tri[:, 0], np.cross(tri[:, 1], tri[:, 2])) / 6.0
    vol = np.where(flip, -vol, vol)
    comp_vol = np.bincount(labels, weights=vol, minlength=n_comp)
    comp_flipped = np.bincount(labels, weights=flip.astype(float), minlength=n_comp)
    comp_size = np.bincount(labels, minlength=n_comp)
    turn = np.where(closed_comp, comp_vol < 0.0, comp_flipped > 0.5 * comp_size)
    flip ^= turn[labels]
    faces = np.where(flip[:, None], faces[:, ::-1], faces)

    manifold = edges.counts[edges.inverse] == 2
    directed = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    key = directed[:, 0].astype(np.int64) * len(vertices) + directed[:, 1]
    _, dir_counts = np.unique(key[manifold], return_counts=True)
    report = CleanReport(
        faces_in=faces_in, dropped_degenerate=n_degenerate, dropped_duplicate=n_duplicate,
        components=int(n_comp), closed_components=int(np.count_nonzero(closed_comp)),
        non_manifold_edges=int(np.count_nonzero(edges.counts > 2)),
        inconsistent_edges=int(np.count_nonzero(dir_counts > 1)),
        flipped=int(np.count_nonzero(flip)))
    if not report.outward_proven:
        warnings.warn(f'clean_mesh: outward orientation not proven ({report.components} '
                      f'component(s), {report.closed_components} closed, '
                      f'{report.non_manifold_edges} non-manifold edge(s), '
                      f'{report.inconsistent_edges} inconsistent edge(s))', MeshWarning,
                      stacklevel=2)
    return TriMesh(vertices, faces), report


def _refuse_strays(vertices: np.ndarray, faces: np.ndarray, labels: np.ndarray,
                   n_comp: int) -> None:
    """MeshError when a component lies more than STRAY_FACTOR x the main body's size away."""
    if n_comp < 2:
        return
    tri_c = vertices[faces].mean(axis=1)
    main = int(np.argmax(np.bincount(labels, minlength=n_comp)))
    pts = vertices[np.unique(faces[labels == main])]
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    size = float(np.linalg.norm(hi - lo))
    # distance of every facet centroid from the main component's bounding box
    gap = np.linalg.norm(np.maximum(lo - tri_c, 0.0) + np.maximum(tri_c - hi, 0.0), axis=1)
    far = gap > STRAY_FACTOR * size
    if np.any(far):
        raise MeshError(f'{int(np.count_nonzero(far))} stray facet(s) up to '
                        f'{float(gap.max()):.3g} m from the main body (size {size:.3g} m, '
                        f'limit {STRAY_FACTOR:g}x): remove them from the mesh')


def _drop_degenerate(vertices: np.ndarray, faces: np.ndarray, rtol: float
                     ) -> tuple[np.ndarray, int]:
    if len(faces) == 0:
        return faces, 0
    repeated = ((faces[:, 0] == faces[:, 1]) | (faces[:, 1] == faces[:, 2])
                | (faces[:, 2] == faces[:, 0]))
    pts = vertices[np.unique(faces)]
    diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0)))
    tri = vertices[faces]
    twice_area = np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    longest = np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max(axis=1)
    # height <= rtol * diag, written without dividing by a possibly zero edge length
    thin = twice_area <= rtol * diag * longest
    bad = repeated | thin | (diag == 0.0)
    return faces[~bad], int(np.count_nonzero(bad))


def _consistent_winding(faces: np.ndarray, edges: _Edges
                        ) -> tuple[np.ndarray, int, np.ndarray]:
    """Component label per face, component count, and a flip mask making windings agree.

    Two faces sharing a manifold edge agree when they traverse it in opposite directions. The
    flip of a face relative to its component's root is the XOR of the disagreements along its
    BFS-tree path, accumulated by pointer jumping (log2(depth) vectorised steps).
    """
    n = len(faces)
    order = np.argsort(edges.inverse, kind='stable')
    start = np.concatenate([[0], np.cumsum(edges.counts)[:-1]])
    pair = start[edges.counts == 2]
    d0, d1 = order[pair], order[pair + 1]              # the two directed edges of each
    fa, fb = d0 // 3, d1 // 3
    disagree = edges.directed[d0, 0] == edges.directed[d1, 0]

    adj = coo_matrix((np.ones(len(fa)), (fa, fb)), shape=(n, n))
    n_comp, labels = connected_components(adj, directed=False)
    roots = np.unique(labels, return_index=True)[1]
    # A virtual node n joined to every component root makes one BFS cover all components.
    rows = np.concatenate([fa, np.full(n_comp, n)])
    cols = np.concatenate([fb, roots])
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n + 1, n + 1)).tocsr()
    _, pred = breadth_first_order(graph, n, directed=False, return_predecessors=True)
    parent = np.append(pred[:n], n).astype(np.int64)
    parent[roots] = n

    # disagreement between each face and its parent, looked up by a sorted pair key
    pair_key = np.minimum(fa, fb).astype(np.int64) * (n + 1) + np.maximum(fa, fb)
    sort = np.argsort(pair_key)
    child = np.arange(n)
    tree = parent[:n] != n
    q = np.minimum(child, parent[:n]).astype(np.int64) * (n + 1) + np.maximum(child, parent[:n])
    pos = np.searchsorted(pair_key[sort], q[tree])
    acc = np.zeros(n + 1, dtype=bool)
    acc[:n][tree] = disagree[sort][pos]
    while np.any(parent != parent[parent]):
        acc = acc ^ acc[parent]
        parent = parent[parent]
    return labels, int(n_comp), acc[:n]


def _closed_components(edges: _Edges, labels: np.ndarray, n_comp: int) -> np.ndarray:
    """(n_comp,) bool: no edge of the component is a boundary or non-manifold edge."""
    open_edge = (edges.counts[edges.inverse] != 2).reshape(-1, 3).any(axis=1)
    return np.bincount(labels, weights=open_edge.astype(float), minlength=n_comp) == 0
