"""Triangle meshes and the per-facet data (centroid, outward normal, area) RFT integrates over.

Convention: faces are wound counter-clockwise seen from outside, so (v1 - v0) x (v2 - v0)
points out of the body. Lengths in m.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Facets:
    """Per-facet data of one or more meshes, in one frame (m, m^2).

    centroids (F, 3), unit outward normals (F, 3), areas (F,).
    """

    centroids: np.ndarray
    normals: np.ndarray
    areas: np.ndarray

    def __len__(self) -> int:
        return int(self.areas.shape[0])

    def transformed(self, rotation: np.ndarray, translation: np.ndarray) -> 'Facets':
        """Facets after x -> R x + t (rotation (3, 3), translation (3,))."""
        r = np.asarray(rotation, dtype=float)
        return Facets(self.centroids @ r.T + np.asarray(translation, dtype=float),
                      self.normals @ r.T, self.areas)

    def subset(self, mask: np.ndarray) -> 'Facets':
        return Facets(self.centroids[mask], self.normals[mask], self.areas[mask])

    @staticmethod
    def concatenate(parts: 'list[Facets]') -> 'Facets':
        if not parts:
            return Facets(np.zeros((0, 3)), np.zeros((0, 3)), np.zeros(0))
        return Facets(np.concatenate([p.centroids for p in parts]),
                      np.concatenate([p.normals for p in parts]),
                      np.concatenate([p.areas for p in parts]))


@dataclass(frozen=True)
class TriMesh:
    """Indexed triangle mesh: vertices (V, 3) in m, faces (F, 3) int, outward winding."""

    vertices: np.ndarray
    faces: np.ndarray

    def __post_init__(self) -> None:
        v = np.ascontiguousarray(self.vertices, dtype=float)
        f = np.ascontiguousarray(self.faces, dtype=np.int64)
        if v.ndim != 2 or v.shape[1] != 3:
            raise ValueError(f'vertices must have shape (V, 3), got {v.shape}')
        if f.ndim != 2 or f.shape[1] != 3:
            raise ValueError(f'faces must have shape (F, 3), got {f.shape}')
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ValueError('face index out of range')
        object.__setattr__(self, 'vertices', v)
        object.__setattr__(self, 'faces', f)

    @property
    def triangles(self) -> np.ndarray:
        """Corner coordinates (F, 3, 3)."""
        return self.vertices[self.faces]

    def facets(self) -> Facets:
        tri = self.triangles
        cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        norm = np.linalg.norm(cross, axis=1)
        safe = np.where(norm > 0.0, norm, 1.0)
        return Facets(tri.mean(axis=1), cross / safe[:, None], 0.5 * norm)

    def signed_volume(self) -> float:
        """Enclosed volume in m^3; positive for outward winding of a closed mesh."""
        tri = self.triangles
        return float(np.einsum('ij,ij->i', tri[:, 0], np.cross(tri[:, 1], tri[:, 2])).sum() / 6.0)

    def transformed(self, rotation: np.ndarray, translation: np.ndarray) -> 'TriMesh':
        r = np.asarray(rotation, dtype=float)
        return TriMesh(self.vertices @ r.T + np.asarray(translation, dtype=float), self.faces)

    def scaled(self, factor: float) -> 'TriMesh':
        return TriMesh(self.vertices * factor, self.faces)

    def flipped(self) -> 'TriMesh':
        """Same surface with reversed winding (normals point the other way)."""
        return TriMesh(self.vertices, self.faces[:, ::-1])

    @staticmethod
    def concatenate(parts: 'list[TriMesh]') -> 'TriMesh':
        verts, faces, offset = [], [], 0
        for m in parts:
            verts.append(m.vertices)
            faces.append(m.faces + offset)
            offset += len(m.vertices)
        return TriMesh(np.concatenate(verts), np.concatenate(faces))
