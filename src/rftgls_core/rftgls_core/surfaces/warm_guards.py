"""Distances and ray crossings of the guard triangles a warm step re-checks (numpy).

The triangles are those of the cold solve's coarse (and dense support-check) wrench meshes
nearest the origin and the load ray; distances are Euclidean in the scaled wrench space.
"""
from __future__ import annotations

import math

import numpy as np

from .newton import cross_rows
from .warm_kernels import HAVE_NUMBA, clearance_bounds


def triangle_distances(vertices: np.ndarray, faces: np.ndarray, point: np.ndarray
                       ) -> np.ndarray:
    """Euclidean distance from `point` (3,) to every triangle `faces` (F, 3) of `vertices`."""
    p = np.asarray(point, dtype=float)
    return _distances(*(vertices[faces[:, i]] - p for i in range(3)))


def _distances(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Distance from the origin to the triangles (a, b, c), each (F, 3).

    Closest point on a triangle (Ericson, Real-Time Collision Detection, 2005, sec. 5.1.5):
    the projection on the plane when it falls inside, else the nearest of the three edges.
    """
    n = cross_rows(b - a, c - a)
    nn = np.einsum('ij,ij->i', n, n)
    # barycentric signs of the projected origin: inside when all three sub-areas agree with n
    inside = ((np.einsum('ij,ij->i', cross_rows(a, b), n) >= 0)
              & (np.einsum('ij,ij->i', cross_rows(b, c), n) >= 0)
              & (np.einsum('ij,ij->i', cross_rows(c, a), n) >= 0) & (nn > 0))
    plane = np.abs(np.einsum('ij,ij->i', n, a)) / np.sqrt(np.maximum(nn, 1e-300))

    def seg(u: np.ndarray, v: np.ndarray) -> np.ndarray:
        e = v - u
        t = np.clip(-np.einsum('ij,ij->i', u, e) / np.maximum(np.einsum('ij,ij->i', e, e),
                                                              1e-300), 0.0, 1.0)
        return np.linalg.norm(u + t[:, None] * e, axis=1)

    edge = np.minimum(np.minimum(seg(a, b), seg(b, c)), seg(c, a))
    return np.where(inside, plane, edge)


def ray_hits(tri: np.ndarray, d: np.ndarray, bary_tol: float = 1e-9,
              dist_rtol: float = 1e-9) -> tuple[np.ndarray, np.ndarray]:
    """raycast.all_hits for a few triangles (T, 3, 3) and a ray from the origin: the sorted
    distinct crossing distances and their triangles (same tolerances, less overhead)."""
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    n_det = cross_rows(e2, e1)
    det = n_det @ d
    det_tol = 1e-12 * np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1)
    ok = np.abs(det) > det_tol
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    q0 = -v0
    q = cross_rows(q0, e1)
    u = (cross_rows(e2, q0) @ d) * inv
    v = (q @ d) * inv
    s = np.einsum('ij,ij->i', e2, q) * inv
    hit = ok & (u >= -bary_tol) & (v >= -bary_tol) & (u + v <= 1.0 + bary_tol) & (s > 0.0)
    idx = np.flatnonzero(hit)
    order = idx[np.argsort(s[idx])]
    ss = s[order]
    keep = np.ones(len(order), dtype=bool)
    keep[1:] = np.diff(ss) > dist_rtol * max(float(np.abs(tri).max()), 1e-300)
    return ss[keep], order[keep]


def clearance_bounds_reference(ws: np.ndarray, faces: np.ndarray, point: np.ndarray
                               ) -> tuple[np.ndarray, np.ndarray]:
    """(upper, lower) bounds of each face's distance to `point`: its nearest vertex's
    distance, and that less its longest edge / sqrt(3). The numpy reference of
    warm_kernels.clearance_bounds (one compiled pass, no (F, 3, 3) temporaries: the dense
    support mesh's 16,000 faces cost 5 ms per anchor here)."""
    upper = np.linalg.norm(ws - point, axis=1)[faces].min(axis=1)
    edge = np.linalg.norm(ws[faces] - ws[np.roll(faces, 1, axis=1)], axis=2).max(axis=1)
    return upper, upper - edge / math.sqrt(3.0)


def triangle_clearance(ws: np.ndarray, faces: np.ndarray, point: np.ndarray,
                       mask: np.ndarray | None = None) -> np.ndarray:
    """Distance of every triangle to `point`; only triangles that can be close are measured
    exactly (inf elsewhere, and where `mask` is False): a triangle is no closer than its
    nearest vertex minus 0.58 of its longest edge (every point of a triangle lies within
    L / sqrt(3) of some vertex)."""
    return triangle_clearances(ws, faces, np.asarray(point, dtype=float)[None, :], mask)[0]


def triangle_clearances(ws: np.ndarray, faces: np.ndarray, points: np.ndarray,
                        mask: np.ndarray | None = None) -> np.ndarray:
    """triangle_clearance of each row of `points` (P, 3): (P, F). The exact distances of
    every point's candidates are taken in one call (numpy's per-call cost, not the
    arithmetic, is most of a few dozen triangles' time)."""
    n = len(faces)
    out = np.full((len(points), n), np.inf)
    ok = np.ones(n, dtype=bool) if mask is None else mask
    if not np.any(ok):
        return out
    k = min(64, int(ok.sum()) - 1)
    rows, cands = [], []
    for i, p in enumerate(points):
        if HAVE_NUMBA:
            upper, lower = clearance_bounds(ws, faces, float(p[0]), float(p[1]), float(p[2]))
        else:
            upper, lower = clearance_bounds_reference(ws, faces, p)
        # enough candidates to know the few closest and a bound on all others
        bound = np.partition(upper[ok], k)[k]
        cand = np.flatnonzero(ok & (lower <= bound))
        out[i] = np.where(ok, np.maximum(lower, 0.0), np.inf)
        rows.append(np.full(len(cand), i))
        cands.append(cand)
    r, c = np.concatenate(rows), np.concatenate(cands)
    f, at = faces[c], points[r]
    out[r, c] = _distances(*(ws[f[:, j]] - at for j in range(3)))
    return out
