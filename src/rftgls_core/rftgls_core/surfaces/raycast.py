"""Ray casting from one fixed origin against a triangle mesh (vectorised Moller-Trumbore).

Every load ray starts at the same point (the origin of W_ext space), so the per-triangle
terms that depend only on the triangle and the origin are precomputed once per mesh
(docs/design/limit-surfaces.md). With e1 = v1 - v0, e2 = v2 - v0, q0 = o - v0:

    det = d . (e2 x e1),  u = d . (e2 x q0) / det,  v = d . (q0 x e1) / det,
    s = e2 . (q0 x e1) / det,

so one ray is three (F, 3) @ (3,) products plus masks, and K rays are (F, 3) @ (3, K).
No back-face culling: the surface is two-sided here. Barycentric weights of (v0, v1, v2) are
(1 - u - v, u, v).

A ray through an edge or a vertex hits 2 or more triangles at the same distance. Hits are
counted as distinct crossings only when their distances differ by more than a relative
tolerance, so such a ray counts once; `on_edge` reports that it happened.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .mesh_loops import HAVE_NUMBA, as_mesh, mesh_winding
from .newton import cross_rows, row_norms


@dataclass(frozen=True)
class PreparedMesh:
    """Per-triangle linear forms for rays from `origin` (all arrays (F, 3) unless noted)."""

    origin: np.ndarray
    n_det: np.ndarray
    n_u: np.ndarray
    q: np.ndarray
    s_num: np.ndarray      # (F,)
    det_tol: np.ndarray    # (F,) |det| below this counts as a ray parallel to the triangle
    length_scale: float    # largest vertex distance from the origin, for distance tolerances
    n_faces: int


def prepare_mesh(vertices: np.ndarray, faces: np.ndarray,
                 origin: np.ndarray | None = None) -> PreparedMesh:
    """Precompute Moller-Trumbore forms for the triangles `faces` (F, 3) of `vertices` (N, 3)."""
    v = np.asarray(vertices, dtype=float)
    f = np.asarray(faces, dtype=np.intp)
    o = np.zeros(3) if origin is None else np.asarray(origin, dtype=float)
    v0, v1, v2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    e1, e2, q0 = v1 - v0, v2 - v0, o - v0
    q = cross_rows(q0, e1)
    # det is d . (e2 x e1) for a unit d; relative to |e1||e2| this is sin(angle(d, plane)).
    det_tol = 1e-12 * row_norms(e1) * row_norms(e2)
    scale = float(row_norms(v - o).max()) if len(v) else 1.0
    return PreparedMesh(origin=o, n_det=cross_rows(e2, e1), n_u=cross_rows(e2, q0), q=q,
                        s_num=np.einsum('ij,ij->i', e2, q), det_tol=det_tol,
                        length_scale=max(scale, np.finfo(float).tiny), n_faces=len(f))


@dataclass(frozen=True)
class RayHits:
    """First hits of K rays. Distances are along the given (unit) directions, mesh units.

    s: (K,) first-hit distance, inf if none. face: (K,) hit triangle, -1 if none.
    bary: (K, 3) barycentric weights of the hit triangle's vertices (NaN if none).
    n_hits: (K,) distinct crossings (hits at equal distance merged). n_raw: (K,) triangles hit.
    on_edge: (K,) the first hit lies on an edge or vertex (within bary_tol).
    """

    s: np.ndarray
    face: np.ndarray
    bary: np.ndarray
    n_hits: np.ndarray
    n_raw: np.ndarray
    on_edge: np.ndarray


def _hit_matrix(mesh: PreparedMesh, dirs: np.ndarray, bary_tol: float):
    """(F, K) arrays: hit mask, s, u, v for unit directions dirs (K, 3)."""
    det = mesh.n_det @ dirs.T
    ok = np.abs(det) > mesh.det_tol[:, None]
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    u = (mesh.n_u @ dirs.T) * inv
    v = (mesh.q @ dirs.T) * inv
    s = mesh.s_num[:, None] * inv
    # Slightly generous barycentric limits so a ray through an edge hits both neighbours
    # (then merged by distance) instead of slipping between them through round-off.
    hit = ok & (u >= -bary_tol) & (v >= -bary_tol) & (u + v <= 1.0 + bary_tol) & (s > 0.0)
    return hit, s, u, v


def cast_rays(mesh: PreparedMesh, directions: np.ndarray, bary_tol: float = 1e-9,
              dist_rtol: float = 1e-9) -> RayHits:
    """First exit of rays origin + s d for unit directions (K, 3) (or one (3,) direction)."""
    dirs = np.atleast_2d(np.asarray(directions, dtype=float))
    hit, s, u, v = _hit_matrix(mesh, dirs, bary_tol)
    k = dirs.shape[0]
    s_hit = np.where(hit, s, np.inf)
    first = np.argmin(s_hit, axis=0) if mesh.n_faces else np.zeros(k, dtype=np.intp)
    cols = np.arange(k)
    n_raw = hit.sum(axis=0)
    has = n_raw > 0
    s_first = np.where(has, s_hit[first, cols], np.inf)
    uf, vf = u[first, cols], v[first, cols]
    bary = np.column_stack([1.0 - uf - vf, uf, vf])
    bary = np.where(has[:, None], np.clip(bary, 0.0, 1.0), np.nan)
    bary = bary / np.where(has, bary.sum(axis=1), 1.0)[:, None]
    n_hits = n_raw.copy()
    multi = np.flatnonzero(n_raw > 1)
    if multi.size:
        # Only rays with several raw hits need de-duplication: sort their distances and count
        # gaps larger than the tolerance (a ray through an edge gives equal distances).
        srt = np.sort(s_hit[:, multi], axis=0)
        tol = dist_rtol * mesh.length_scale
        fin = np.isfinite(srt)
        gaps = np.diff(np.where(fin, srt, 0.0), axis=0)
        distinct = fin[1:] & (gaps > tol)
        n_hits[multi] = 1 + distinct.sum(axis=0)
    on_edge = has & (np.nanmin(np.where(has[:, None], bary, 1.0), axis=1) <= 10 * bary_tol)
    # Several triangles at the first distance also means an edge/vertex crossing.
    if multi.size:
        tol = dist_rtol * mesh.length_scale
        near_first = (np.abs(s_hit[:, multi] - s_first[multi]) <= tol).sum(axis=0)
        on_edge[multi] |= near_first > 1
    face = np.where(has, first, -1)
    return RayHits(s=s_first, face=face, bary=bary, n_hits=n_hits, n_raw=n_raw, on_edge=on_edge)


def all_hits(mesh: PreparedMesh, direction: np.ndarray, bary_tol: float = 1e-9,
             dist_rtol: float = 1e-9) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every distinct crossing of one ray, sorted by distance: (s (H,), face (H,), bary (H, 3))."""
    d = np.asarray(direction, dtype=float).reshape(1, 3)
    hit, s, u, v = _hit_matrix(mesh, d, bary_tol)
    idx = np.flatnonzero(hit[:, 0])
    order = idx[np.argsort(s[idx, 0])]
    ss = s[order, 0]
    keep = np.ones(len(order), dtype=bool)
    keep[1:] = np.diff(ss) > dist_rtol * mesh.length_scale
    order, ss = order[keep], ss[keep]
    uu, vv = u[order, 0], v[order, 0]
    bary = np.clip(np.column_stack([1.0 - uu - vv, uu, vv]), 0.0, 1.0)
    bary /= np.maximum(bary.sum(axis=1, keepdims=True), np.finfo(float).tiny)
    return ss, order, bary


def winding_number(vertices: np.ndarray, faces: np.ndarray,
                   point: np.ndarray | None = None) -> float:
    """Generalised winding number of a closed, outward-oriented mesh about `point`.

    Sum of the signed solid angles of the triangles seen from the point (Van Oosterom and
    Strackee) over 4 pi: 1 inside, 0 outside, fractional near or on the surface or when the
    mesh is not closed. Robust where a ray-parity test is not (rays through edges). One
    compiled loop (mesh_loops.py) with numba, else winding_number_numpy.
    """
    if not HAVE_NUMBA:
        return winding_number_numpy(vertices, faces, point)
    p = (0.0, 0.0, 0.0) if point is None else tuple(float(x) for x in point)
    return float(mesh_winding(*as_mesh(vertices, faces), *p))


def winding_number_numpy(vertices: np.ndarray, faces: np.ndarray,
                         point: np.ndarray | None = None) -> float:
    """winding_number as numpy expressions vectorised over the triangles (the reference of
    the compiled loop; it sums pairwise, the loop in order: equal to ~F eps)."""
    p = np.zeros(3) if point is None else np.asarray(point, dtype=float)
    v = np.asarray(vertices, dtype=float) - p
    f = np.asarray(faces, dtype=np.intp)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
    num = np.einsum('ij,ij->i', a, np.cross(b, c))
    den = (la * lb * lc + np.einsum('ij,ij->i', a, b) * lc + np.einsum('ij,ij->i', a, c) * lb
           + np.einsum('ij,ij->i', b, c) * la)
    return float(2.0 * np.arctan2(num, den).sum() / (4.0 * np.pi))
