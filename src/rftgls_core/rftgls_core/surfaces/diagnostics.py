"""Checks on sampled limit surfaces: folds, pinches, closedness, maximum power inequality.

All inputs are in the scaled spaces (dimensionless wrenches, unit scaled twists), so
tolerances are relative to a surface of size about 1.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components


def face_normals(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Unnormalised right-hand normals (F, 3) (twice the area vector)."""
    p = np.asarray(points, dtype=float)
    f = np.asarray(faces, dtype=np.intp)
    return np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])


def fold_mask(points: np.ndarray, faces: np.ndarray, origin: np.ndarray | None = None,
              rtol: float = 1e-9) -> np.ndarray:
    """(F,) True for non-degenerate faces whose outward normal points toward the origin.

    On a star-shaped surface about the origin (every ray leaves once) no face does. Faces of
    zero area (all vertices on one wrench) cannot be hit and are not counted as folds.
    """
    o = np.zeros(3) if origin is None else np.asarray(origin, dtype=float)
    p = np.asarray(points, dtype=float) - o
    f = np.asarray(faces, dtype=np.intp)
    n = face_normals(p, f)
    c = p[f].mean(axis=1)
    nn = np.linalg.norm(n, axis=1)
    scale = max(float(np.max(np.linalg.norm(p, axis=1))), np.finfo(float).tiny)
    real = nn > 1e-14 * scale * scale
    return real & (np.einsum('ij,ij->i', n, c) < -rtol * nn * np.linalg.norm(c, axis=1))


def unique_edges(faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Undirected edges (E, 2) (sorted pairs) and how many faces use each (E,)."""
    f = np.asarray(faces, dtype=np.intp)
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    e.sort(axis=1)
    edges, counts = np.unique(e, axis=0, return_counts=True)
    return edges, counts


def collapsed_vertices(wrenches_s: np.ndarray, twists_s: np.ndarray, faces: np.ndarray,
                       ratio: float = 1e-3, edges: np.ndarray | None = None) -> np.ndarray:
    """(N,) True for vertices on an edge where distinct twists give (almost) one wrench.

    Edge stretch = |W_i - W_j| / angle(t_i, t_j). An edge is collapsed when its stretch is
    below `ratio` times the median stretch: the unique twist-wrench pair assumption fails
    there (e.g. a thin plate sliding in its own plane), so no slip twist can be read off.
    edges: the mesh's unique edges when the caller has them (a fixed connectivity).
    """
    if edges is None:
        edges, _ = unique_edges(faces)
    w = np.asarray(wrenches_s, dtype=float)
    t = np.asarray(twists_s, dtype=float)
    dw = np.linalg.norm(w[edges[:, 0]] - w[edges[:, 1]], axis=1)
    cosang = np.clip(np.einsum('ij,ij->i', t[edges[:, 0]], t[edges[:, 1]]), -1.0, 1.0)
    ang = np.arccos(cosang)
    stretch = dw / np.maximum(ang, np.finfo(float).tiny)
    med = float(np.median(stretch))
    bad = stretch < ratio * med
    out = np.zeros(len(w), dtype=bool)
    out[edges[bad].ravel()] = True
    return out


@dataclass(frozen=True)
class MeshTopology:
    """Closedness of a triangle mesh: every edge in exactly two faces, Euler characteristic."""

    n_vertices: int
    n_edges: int
    n_faces: int
    euler: int
    nonmanifold_edges: int    # edges used by more than two faces
    open_edges: int           # edges used by one face
    components: int           # connected pieces of the surface

    @property
    def closed_genus0(self) -> bool:
        return (self.nonmanifold_edges == 0 and self.open_edges == 0 and self.euler == 2
                and self.components == 1)


def mesh_topology(faces: np.ndarray) -> MeshTopology:
    f = np.asarray(faces, dtype=np.intp)
    if len(f) == 0:
        return MeshTopology(0, 0, 0, 0, 0, 0, 0)
    used = np.unique(f)
    edges, counts = unique_edges(f)
    # Components over the used vertices, linked by edges.
    remap = np.full(int(used.max()) + 1, -1, dtype=np.intp)
    remap[used] = np.arange(len(used))
    a, b = remap[edges[:, 0]], remap[edges[:, 1]]
    g = coo_matrix((np.ones(len(a)), (a, b)), shape=(len(used), len(used)))
    ncomp, _ = connected_components(g, directed=False)
    return MeshTopology(n_vertices=len(used), n_edges=len(edges), n_faces=len(f),
                        euler=len(used) - len(edges) + len(f),
                        nonmanifold_edges=int(np.sum(counts > 2)),
                        open_edges=int(np.sum(counts == 1)), components=int(ncomp))


@dataclass(frozen=True)
class MaxPowerReport:
    """Maximum power inequality t_i . W_j <= t_i . W_i over all sample pairs (scaled).

    Holds for convex surfaces obeying normality. Violations mean gradient (normality) twists
    (ellipsoid, halfspaces) are not trustworthy; use barycentric twists.
    """

    fraction: float      # fraction of ordered pairs (i != j) violating by more than tol
    worst: float         # largest violation t_i.(W_j - W_i), relative to the max support value
    worst_pair: tuple[int, int]


def max_power_check(twists_s: np.ndarray, wrenches_s: np.ndarray, tol: float = 1e-9,
                    chunk: int = 512) -> MaxPowerReport:
    """O(N^2) check in row chunks (N = 2000: a few tens of ms)."""
    t = np.asarray(twists_s, dtype=float)
    w = np.asarray(wrenches_s, dtype=float)
    h = np.einsum('ij,ij->i', t, w)
    scale = max(float(np.max(np.abs(h))), np.finfo(float).tiny)
    n = len(t)
    count, worst, pair = 0, -np.inf, (-1, -1)
    for i0 in range(0, n, chunk):
        m = t[i0:i0 + chunk] @ w.T - h[i0:i0 + chunk, None]
        count += int(np.sum(m > tol * scale))
        k = int(np.argmax(m))
        if m.flat[k] > worst:
            worst, pair = float(m.flat[k]), (i0 + k // n, k % n)
    pairs = max(n * (n - 1), 1)
    return MaxPowerReport(fraction=count / pairs, worst=max(worst, 0.0) / scale, worst_pair=pair)
