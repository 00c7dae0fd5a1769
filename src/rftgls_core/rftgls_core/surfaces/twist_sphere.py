"""The twist sphere: n unit scaled twists and their outward triangulation, shared by every method.

Every limit-surface method samples the same sphere of unit twists in the scaled metric
(Fibonacci points, sampling.py) and most of them need its triangulation too: the convex hull of
unit vectors is their spherical Delaunay triangulation, so moving each vertex to its wrench
turns it into a closed genus-0 mesh of the limit surface (docs/design/limit-surfaces.md). It
depends on neither the pose nor the scaling, so one cached instance serves a whole map.

A leaf module: numpy, scipy and the two geometry helpers below it, nothing else.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np
from scipy.spatial import ConvexHull

from .diagnostics import face_normals, unique_edges
from .sampling import fibonacci_sphere
from .scaling import Scaling


def orient_outward(points: np.ndarray, faces: np.ndarray,
                   centre: np.ndarray | None = None) -> np.ndarray:
    """Reorder each face (F, 3) so its right-hand normal points away from `centre` (default 0)."""
    c = np.zeros(3) if centre is None else np.asarray(centre, dtype=float)
    f = np.array(faces, dtype=np.intp, copy=True)
    n = face_normals(points, f)
    centroid = points[f].mean(axis=1) - c
    flip = np.einsum('ij,ij->i', n, centroid) < 0.0
    f[flip, 1], f[flip, 2] = f[flip, 2].copy(), f[flip, 1].copy()
    return f


@dataclass(frozen=True)
class TwistSphere:
    """n unit scaled twists (Fibonacci) and their outward sphere triangulation (2n - 4 faces)."""

    twists_scaled: np.ndarray   # (n, 3) unit vectors, scaled metric
    faces: np.ndarray           # (2n-4, 3) vertex indices, outward

    @property
    def n(self) -> int:
        return len(self.twists_scaled)

    @classmethod
    def build(cls, n: int) -> TwistSphere:
        """The cached sphere of n twists (n >= 4): built once per n, read-only."""
        return _sphere(int(n))

    def twists_raw(self, scaling: Scaling) -> np.ndarray:
        """(n, 3) raw unit twist directions (vx, vz, wy) for wrench functions."""
        return scaling.twist_from_scaled(self.twists_scaled)

    @cached_property
    def edges(self) -> np.ndarray:
        """Unique undirected edges (E, 2): the same for every pose, so computed once."""
        return unique_edges(self.faces)[0]


@lru_cache(maxsize=8)
def _sphere(n: int) -> TwistSphere:
    ts = fibonacci_sphere(n)
    hull = ConvexHull(ts)
    if len(hull.vertices) != n:
        raise RuntimeError(f'sphere hull dropped {n - len(hull.vertices)} of {n} twists')
    faces = orient_outward(ts, hull.simplices)
    faces.setflags(write=False)
    ts.setflags(write=False)
    return TwistSphere(twists_scaled=ts, faces=faces)
