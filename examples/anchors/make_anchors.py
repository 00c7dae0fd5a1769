"""Write the three example anchors of this folder as STL files (mm), each with its mesh origin
at its tether point: `python make_anchors.py` (rftgls_core installed; deterministic, so the
files in the repository are exactly what this writes).

- ellipsoid.stl: the Fig. 13 ellipsoid (semi-axes 30 x 20 x 12.5 mm), long axis along +x
  from the tether point at its end (the same body as `rftgls figure fig13`).
- plate.stl: a flat plate anchor, 60 x 40 x 3 mm, tether at the middle of its top face.
- finned.stl: a finned stake, four 4 mm thick fins in a cross of 40 mm span, 80 mm long
  along -z from the tether point on its top face.

Plate and stake are prisms whose facets are mirror-symmetric like their shapes (see `prism`).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from rftgls_core.geometry.mesh import TriMesh
from rftgls_core.geometry.shapes import ellipsoid
from rftgls_core.geometry.stl import write_stl

HERE = Path(__file__).resolve().parent


def cross_polygon(span: float, thickness: float) -> np.ndarray:
    """The 12 corners (counter-clockwise, m) of a plus-shaped cross section, centred."""
    s, t = span / 2.0, thickness / 2.0
    return np.array([[t, t], [s, t], [s, -t], [t, -t], [t, -s], [-t, -s], [-t, -t], [-s, -t],
                     [-s, t], [-t, t], [-t, s], [t, s]])[::-1]


def rectangle_polygon(lx: float, ly: float, per_side: int) -> np.ndarray:
    """Corners and edge points (counter-clockwise, m) of an lx x ly rectangle, centred."""
    u = np.linspace(-0.5, 0.5, per_side + 1)[:-1]
    sides = [np.column_stack([u * lx, np.full_like(u, -ly / 2)]),
             np.column_stack([np.full_like(u, lx / 2), u * ly]),
             np.column_stack([-u * lx, np.full_like(u, ly / 2)]),
             np.column_stack([np.full_like(u, -lx / 2), -u * ly])]
    return np.vstack(sides)


def prism(polygon: np.ndarray, length: float, n_len: int) -> TriMesh:
    """A closed prism: the star-shaped polygon (about its centre, counter-clockwise seen from
    +z) extruded from z = 0 down to z = -length, side walls split into n_len rings, caps
    fanned from the centre. Each wall quad is split into four triangles about its centre, so
    a mirror symmetry of the polygon is a symmetry of the facets too (the posed anchor's symmetry
    check compares facets: docs/design/six-d.md). Outward winding."""
    k = len(polygon)
    rings = [np.column_stack([polygon, np.full(k, -length * i / n_len)])
             for i in range(n_len + 1)]
    verts = list(np.vstack(rings))
    faces = []
    for i in range(n_len):
        for j in range(k):
            a, b = i * k + j, i * k + (j + 1) % k
            c, d = a + k, b + k
            m = len(verts)
            verts.append((verts[a] + verts[b] + verts[c] + verts[d]) / 4.0)
            faces += [(a, c, m), (c, d, m), (d, b, m), (b, a, m)]
    top_c, bot_c = len(verts), len(verts) + 1
    verts += [np.array([0.0, 0.0, 0.0]), np.array([0.0, 0.0, -length])]
    last = n_len * k
    for j in range(k):
        faces.append((top_c, j, (j + 1) % k))
        faces.append((bot_c, last + (j + 1) % k, last + j))
    mesh = TriMesh(np.array(verts), np.array(faces))
    return mesh if mesh.signed_volume() > 0 else mesh.flipped()


def anchors() -> dict[str, TriMesh]:
    a = 0.030
    ell = ellipsoid(a, 0.020, 0.0125, 3).transformed(np.eye(3), np.array([a, 0.0, 0.0]))
    flat = prism(rectangle_polygon(0.060, 0.040, 12), 0.003, 1)
    finned = prism(cross_polygon(0.040, 0.004), 0.080, 16)
    return {'ellipsoid': ell, 'plate': flat, 'finned': finned}


def main() -> None:
    for name, mesh in anchors().items():
        assert mesh.signed_volume() > 0.0 and math.isfinite(mesh.signed_volume())
        write_stl(HERE / f'{name}.stl', mesh, units='mm', name=name)
        print(f'wrote {name}.stl: {len(mesh.faces)} facets, '
              f'{mesh.signed_volume() * 1e6:.2f} cm^3')


if __name__ == '__main__':
    main()
