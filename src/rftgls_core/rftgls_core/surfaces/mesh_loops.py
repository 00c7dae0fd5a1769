"""Whole-mesh reductions about one point, compiled by numba when it is installed.

The distance from a point to a triangle mesh (maps/edge.py) and the winding number of a mesh
about a point (raycast.py) each reduce every triangle of a twist-sphere mesh (16,000 on the
8,000-twist sphere of the support check) to one number. As numpy expressions they make some
40 passes over (F, 3) temporaries, which took over half of a support-edge corner's time in a
map build; one loop per triangle keeps its numbers in registers.

`mesh_distance` does point_mesh_distance's operations in the same order (no fast-math, so no
fused multiply-adds either; the dot products in einsum's order, `_dot`), and a minimum does
not depend on the order it is taken in: its result is the numpy expression's to the last bit
(tests/core/test_maps_edge.py compares the two). `mesh_winding` sums the triangles'
solid angles in triangle order where numpy sums pairwise, and takes arctan2 from the C
library: it differs from the numpy expression by rounding, ~F eps of the sum (1e-12 on
16,000 triangles), and is only ever compared with thresholds a closed mesh's winding number
(0 or 1 away from the surface) is nowhere near.
"""
from __future__ import annotations

import math

import numpy as np

try:
    import numba
except ImportError:  # pragma: no cover - machines without numba use the numpy expressions
    numba = None  # type: ignore[assignment]

HAVE_NUMBA = numba is not None


def _dot(x0, x1, x2, y0, y1, y2):
    """x . y summed as numpy's einsum('ij,ij->i') sums three terms: the first and the last,
    then the middle one (the same on its baseline, AVX2 and AVX-512 dispatch; checked
    against einsum by tests/core/test_maps_edge.py). Norms (np.linalg.norm) sum in order."""
    return (x0 * y0 + x2 * y2) + x1 * y1


def mesh_distance(vertices, faces, px, py, pz):
    """Smallest Euclidean distance from (px, py, pz) to the triangles faces (F, 3) of
    vertices (N, 3): per triangle the closest point of its plane when that projects inside,
    else the closest point of its edges (point_mesh_distance's arithmetic)."""
    best = math.inf
    for k in range(faces.shape[0]):
        i, j, m = faces[k, 0], faces[k, 1], faces[k, 2]
        ax, ay, az = vertices[i, 0] - px, vertices[i, 1] - py, vertices[i, 2] - pz
        bx, by, bz = vertices[j, 0] - px, vertices[j, 1] - py, vertices[j, 2] - pz
        cx, cy, cz = vertices[m, 0] - px, vertices[m, 1] - py, vertices[m, 2] - pz
        e0x, e0y, e0z = bx - ax, by - ay, bz - az
        e1x, e1y, e1z = cx - ax, cy - ay, cz - az
        nx = e0y * e1z - e0z * e1y
        ny = e0z * e1x - e0x * e1z
        nz = e0x * e1y - e0y * e1x
        nn = _dot(nx, ny, nz, nx, ny, nz)
        ok = nn > 0.0
        t = _dot(ax, ay, az, nx, ny, nz) / nn if ok else 0.0
        qx, qy, qz = t * nx, t * ny, t * nz
        d00 = _dot(e0x, e0y, e0z, e0x, e0y, e0z)
        d01 = _dot(e0x, e0y, e0z, e1x, e1y, e1z)
        d11 = _dot(e1x, e1y, e1z, e1x, e1y, e1z)
        rx, ry, rz = qx - ax, qy - ay, qz - az
        d20 = _dot(rx, ry, rz, e0x, e0y, e0z)
        d21 = _dot(rx, ry, rz, e1x, e1y, e1z)
        den = d00 * d11 - d01 * d01
        good = ok and den > 0.0
        if not good:
            den = 1.0
        bv = (d11 * d20 - d01 * d21) / den
        bw = (d00 * d21 - d01 * d20) / den
        if good and bv >= 0.0 and bw >= 0.0 and bv + bw <= 1.0:
            best = min(best, abs(t) * math.sqrt(nn))
        # The edges too when the plane's point is inside (numpy's expression takes the
        # minimum of both, and rounding may put an edge an ulp closer).
        for ux, uy, uz, vx, vy, vz in ((ax, ay, az, bx, by, bz), (bx, by, bz, cx, cy, cz),
                                       (cx, cy, cz, ax, ay, az)):
            ex, ey, ez = vx - ux, vy - uy, vz - uz
            ee = _dot(ex, ey, ez, ex, ey, ez)
            s = -_dot(ux, uy, uz, ex, ey, ez) / (ee if ee > 0.0 else 1.0)
            s = min(max(s, 0.0), 1.0)
            wx, wy, wz = ux + s * ex, uy + s * ey, uz + s * ez
            best = min(best, math.sqrt(wx * wx + wy * wy + wz * wz))
    return best


def mesh_winding(vertices, faces, px, py, pz):
    """Generalised winding number of the mesh about (px, py, pz): the triangles' signed solid
    angles (Van Oosterom and Strackee) summed in triangle order, over 4 pi."""
    total = 0.0
    for k in range(faces.shape[0]):
        i, j, m = faces[k, 0], faces[k, 1], faces[k, 2]
        ax, ay, az = vertices[i, 0] - px, vertices[i, 1] - py, vertices[i, 2] - pz
        bx, by, bz = vertices[j, 0] - px, vertices[j, 1] - py, vertices[j, 2] - pz
        cx, cy, cz = vertices[m, 0] - px, vertices[m, 1] - py, vertices[m, 2] - pz
        la = math.sqrt(ax * ax + ay * ay + az * az)
        lb = math.sqrt(bx * bx + by * by + bz * bz)
        lc = math.sqrt(cx * cx + cy * cy + cz * cz)
        num = _dot(ax, ay, az, by * cz - bz * cy, bz * cx - bx * cz, bx * cy - by * cx)
        den = (la * lb * lc + _dot(ax, ay, az, bx, by, bz) * lc
               + _dot(ax, ay, az, cx, cy, cz) * lb + _dot(bx, by, bz, cx, cy, cz) * la)
        total += math.atan2(num, den)
    return 2.0 * total / (4.0 * math.pi)


if numba is not None:
    _jit = numba.njit(cache=True, nogil=True)
    _dot = numba.njit(cache=True, nogil=True, inline='always')(_dot)
    mesh_distance = _jit(mesh_distance)
    mesh_winding = _jit(mesh_winding)


def as_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """(vertices as contiguous float64 (N, 3), faces as contiguous intp (F, 3)): one array
    type per argument, so the compiled loops are compiled once."""
    return (np.ascontiguousarray(vertices, dtype=np.float64),
            np.ascontiguousarray(faces, dtype=np.intp))
