"""A single rigid body from an STL file, posed in the world with a tether point: a PosedAnchor.

The command-line form (`rftgls capacity --mesh ...`) places the mesh like `rftgls wrench`: the
mesh origin at `position` (m, world, free surface z = 0), turned by roll-pitch-yaw (rad here,
degrees at the CLI; extrinsic x, y, z about the mesh origin, geometry/transforms.py). The tether
point and the centre of mass are world points (m). Without a centre of mass the body is taken
as homogeneous: the centroid of its volume.

Checks (docs/design/six-d.md, "Bad input"): the mesh must be a closed, consistently wound shell
(inside-out shells are turned around with a warning; an open one is refused: a capacity needs
an inside for the centre of mass and the tether check), and the tether must attach on or
outside the surface, not inside the body.
"""
from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .geometry.mesh import TriMesh
from .geometry.stl import MeshError, read_stl
from .geometry.transforms import rpy_matrix
from .geometry.validate import MeshWarning, clean_mesh
from .posed import PosedAnchor
from .surfaces.raycast import winding_number

# Winding number above which a point is inside the body: 1 strictly inside, 1/2 on a flat
# face, up to 3/4 in a right-angled concave edge, 0 outside.
INSIDE_WINDING = 0.9


def load_body_mesh(path: str | Path, units: str = 'mm') -> TriMesh:
    """A closed, outward-wound mesh from an STL file (m); MeshError otherwise (one line)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter('always')
        try:
            mesh, report = clean_mesh(read_stl(path, units=units))
        except MeshError as exc:
            raise MeshError(exc if str(path) in str(exc) else f'{path}: {exc}') from None
    if not report.outward_proven:
        raise MeshError(f'{path}: not a closed, consistently wound body ({report.components} '
                        f'component(s), {report.closed_components} closed, '
                        f'{report.non_manifold_edges} non-manifold edge(s)): a capacity needs '
                        'a watertight mesh')
    for w in caught:    # repairs that succeeded (degenerate facets dropped, ...)
        warnings.warn(str(w.message), MeshWarning, stacklevel=2)
    if report.flipped == report.faces_in - report.dropped_degenerate - report.dropped_duplicate:
        warnings.warn(f'{path}: the mesh was inside out; its winding was reversed',
                      MeshWarning, stacklevel=2)
    elif report.flipped:
        warnings.warn(f'{path}: {report.flipped} facet(s) had inconsistent winding and were '
                      'turned', MeshWarning, stacklevel=2)
    return mesh


def volume_centroid(mesh: TriMesh) -> np.ndarray:
    """Centroid of the enclosed volume of a closed outward mesh, m (signed tetrahedra)."""
    tri = mesh.triangles
    o = tri.reshape(-1, 3).mean(axis=0)
    a, b, c = tri[:, 0] - o, tri[:, 1] - o, tri[:, 2] - o
    vol = np.einsum('ij,ij->i', a, np.cross(b, c)) / 6.0
    return o + (vol[:, None] * (a + b + c) / 4.0).sum(axis=0) / vol.sum()


def _inside(mesh: TriMesh, p: np.ndarray) -> bool:
    """p is inside the closed mesh by more than round-off: it and its six neighbours at
    1e-6 of the body's size along the axes all have a winding number above INSIDE_WINDING (a
    tether on the surface, as written by hand or exported, is not inside)."""
    size = float(np.ptp(mesh.vertices, axis=0).max())
    probes = p + np.vstack([np.zeros(3), 1e-6 * size * np.vstack([np.eye(3), -np.eye(3)])])
    return all(winding_number(mesh.vertices, mesh.faces, q) > INSIDE_WINDING for q in probes)


@dataclass(frozen=True)
class RigidBody:
    """One rigid body: its mesh in its own frame (m), mass (kg) and, optionally, the centre of
    mass in that frame (m; None: the volume centroid)."""

    name: str
    mesh: TriMesh
    mass: float
    com_body: tuple[float, float, float] | None = None

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass) and self.mass >= 0.0):
            raise ValueError(f'mass must be a finite number >= 0 kg, got {self.mass!r}')

    def pose(self, position, rpy_rad, tether, com_world=None) -> PosedAnchor:
        """Posed in the world with its tether point (m); com_world overrides the centre of
        mass (m, world). ValueError when the tether point is inside the body."""
        rot = rpy_matrix(*np.asarray(rpy_rad, dtype=float))
        pos = np.asarray(position, dtype=float).reshape(3)
        posed = self.mesh.transformed(rot, pos)
        p = np.asarray(tether, dtype=float).reshape(3)
        if not np.all(np.isfinite(p)):
            raise ValueError(f'tether point must be finite, got {p.tolist()}')
        if _inside(posed, p):
            raise ValueError(f'tether point {p.tolist()} m is inside the body {self.name!r}: '
                             'attach it on or outside the surface')
        if com_world is not None:
            com = np.asarray(com_world, dtype=float).reshape(3)
        elif self.com_body is not None:
            com = rot @ np.asarray(self.com_body, dtype=float) + pos
        else:
            com = volume_centroid(posed)
        f = posed.facets()
        # L_c: the RMS facet distance from p, area-weighted (the body's lever arm about p).
        lc = float(np.sqrt(np.average(np.sum((f.centroids - p) ** 2, axis=1), weights=f.areas)))
        return PosedAnchor(name=self.name, facets=f, ref=p, mass=self.mass, com=com,
                           char_length=max(lc, 1e-6))
