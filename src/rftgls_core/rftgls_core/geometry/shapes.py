"""Parametric solids as closed, outward-wound TriMesh in metres.

RFT samples depth at facet centroids, so every shape here can be refined (subdivisions,
n_arc) until the force converges. Box-like solids (box, plate, C-leg) share one generator: the
boundary of a structured block of parameter cells, triangulated so that its winding is outward
in parameter space, then mapped to space by an orientation-preserving map (positive Jacobian),
which keeps the winding outward.
"""
from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from .mesh import TriMesh

# ------------------------------------------------------------------------ structured blocks

def _block_surface(counts: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Boundary of the lattice block [0, n0] x [0, n1] x [0, n2], outward for a right-handed
    parameter frame: integer lattice points (V, 3) and faces (F, 3), two triangles per cell.
    """
    counts = (int(counts[0]), int(counts[1]), int(counts[2]))
    pts, faces, offset = [], [], 0
    for a in range(3):
        b, c = (a + 1) % 3, (a + 2) % 3          # e_a = e_b x e_c (cyclic, right-handed)
        for side in (0, counts[a]):
            # outward +e_a: grid (u along b, v along c); outward -e_a: swap them
            ua, va = (b, c) if side else (c, b)
            nu, nv = counts[ua], counts[va]
            i, j = np.meshgrid(np.arange(nu + 1), np.arange(nv + 1), indexing='ij')
            lat = np.zeros((nu + 1, nv + 1, 3), dtype=np.int64)
            lat[..., a], lat[..., ua], lat[..., va] = side, i, j
            pts.append(lat.reshape(-1, 3))
            idx = offset + np.arange((nu + 1) * (nv + 1)).reshape(nu + 1, nv + 1)
            p00, p10 = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel()
            p11, p01 = idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
            faces.append(np.stack([np.stack([p00, p10, p11], 1), np.stack([p00, p11, p01], 1)],
                                  axis=1).reshape(-1, 3))
            offset += (nu + 1) * (nv + 1)
    # weld the shared edges: equal integer lattice points are one vertex
    lattice, inverse = np.unique(np.concatenate(pts), axis=0, return_inverse=True)
    return lattice, inverse.reshape(-1)[np.concatenate(faces)]


def _mapped_block(counts: tuple[int, int, int],
                  to_space: Callable[[np.ndarray], np.ndarray]) -> TriMesh:
    """Block surface with lattice points in [0, 1]^3 mapped through to_space ((V, 3) -> (V, 3))."""
    lattice, faces = _block_surface(counts)
    unit = lattice / np.asarray(counts, dtype=float)
    return TriMesh(to_space(unit), faces)


def _positive(**values: float) -> None:
    for name, value in values.items():
        if not (math.isfinite(value) and value > 0.0):
            raise ValueError(f'{name} must be a positive finite number, got {value!r}')


def _cells(lengths: tuple[float, float, float], subdivisions: int | tuple[int, int, int]
           ) -> tuple[int, int, int]:
    """Cells per axis: a tuple as given, or an int meaning cells along the longest side (the
    others get proportionally many, at least one) so the cells stay close to square."""
    if isinstance(subdivisions, (tuple, list)):
        if len(subdivisions) != 3 or min(subdivisions) < 1:
            raise ValueError(f'subdivisions must be 3 positive ints, got {subdivisions!r}')
        return (int(subdivisions[0]), int(subdivisions[1]), int(subdivisions[2]))
    n = int(subdivisions)
    if n < 1:
        raise ValueError(f'subdivisions must be >= 1, got {subdivisions!r}')
    longest = max(lengths)
    c0, c1, c2 = (max(1, math.ceil(n * length / longest - 1e-9)) for length in lengths)
    return (c0, c1, c2)


# ------------------------------------------------------------------------------ box, plate

def box(lx: float, ly: float, lz: float, subdivisions: int | tuple[int, int, int] = 1
        ) -> TriMesh:
    """Axis-aligned box centred at the origin, side lengths in m.

    subdivisions: cells along the longest side (int) or per axis (nx, ny, nz); every face is
    split into that grid of rectangles, two triangles each.
    """
    _positive(lx=lx, ly=ly, lz=lz)
    size = np.array([lx, ly, lz], dtype=float)
    return _mapped_block(_cells((lx, ly, lz), subdivisions), lambda u: (u - 0.5) * size)


def plate(lx: float, ly: float, thickness: float,
          subdivisions: int | tuple[int, int, int] = 1) -> TriMesh:
    """Flat plate: a box lx x ly in the x-y plane, `thickness` along z, centred at the origin."""
    return box(lx, ly, thickness, subdivisions)


# ------------------------------------------------------------------------------- C-leg

def c_leg(arc_diameter: float = 0.090, thickness: float = 0.005, width: float = 0.010,
          n_arc: int = 24, arc_angle: float = math.pi, n_thick: int = 1, n_width: int = 1
          ) -> TriMesh:
    """C-shaped leg of a RHex-type robot: an annular sector swept `width` along y.

    Local frame (m): the hip (axle attachment) is at the origin, the axle along y. The
    centreline is the circular arc of radius R = arc_diameter / 2 about the centre (0, 0, -R),
        c(t) = (R sin t, 0, -R + R cos t),  t in [0, arc_angle],
    so t = 0 is the hip, the arc bulges toward +x, and at arc_angle = pi the toe is at
    (0, 0, -arc_diameter). The cross-section spans radii R +- thickness / 2 and y in
    [-width / 2, width / 2]. Both ends are closed by flat caps.

    n_arc segments along the arc (chords); n_thick, n_width cells across the section.
    The enclosed volume tends to arc_angle * R * thickness * width as n_arc grows.
    """
    _positive(arc_diameter=arc_diameter, thickness=thickness, width=width, arc_angle=arc_angle)
    radius = 0.5 * arc_diameter
    if thickness >= arc_diameter:
        raise ValueError(f'thickness {thickness} must be below arc_diameter {arc_diameter}')
    if arc_angle >= 2.0 * math.pi:
        raise ValueError(f'arc_angle must be below 2 pi (the ends would meet), got {arc_angle}')
    if min(n_arc, n_thick, n_width) < 1:
        raise ValueError('n_arc, n_thick and n_width must be >= 1')
    r_in = radius - 0.5 * thickness

    def to_space(u: np.ndarray) -> np.ndarray:
        # parameters (r, t, y): their unit vectors (radial, tangent, y) form a right-handed
        # frame, so the block's outward winding maps to an outward winding here.
        r = r_in + thickness * u[:, 0]
        t = arc_angle * u[:, 1]
        y = width * (u[:, 2] - 0.5)
        return np.stack([r * np.sin(t), y, -radius + r * np.cos(t)], axis=1)

    return _mapped_block((n_thick, n_arc, n_width), to_space)


def annular_sector_volume(arc_diameter: float, thickness: float, width: float,
                          arc_angle: float, n_arc: int | None = None) -> float:
    """Volume (m^3) of the exact C-leg solid, or of its n_arc-chord polygonal mesh."""
    radius = 0.5 * arc_diameter
    ring = (radius + 0.5 * thickness) ** 2 - (radius - 0.5 * thickness) ** 2
    if n_arc is None:
        return 0.5 * arc_angle * ring * width
    return 0.5 * n_arc * math.sin(arc_angle / n_arc) * ring * width


# ----------------------------------------------------------------------- spheres, ellipsoids

def _icosahedron() -> tuple[np.ndarray, np.ndarray]:
    p = (1.0 + math.sqrt(5.0)) / 2.0
    verts = np.array([[-1, p, 0], [1, p, 0], [-1, -p, 0], [1, -p, 0],
                      [0, -1, p], [0, 1, p], [0, -1, -p], [0, 1, -p],
                      [p, 0, -1], [p, 0, 1], [-p, 0, -1], [-p, 0, 1]], dtype=float)
    faces = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
                      [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
                      [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
                      [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], dtype=np.int64)
    return verts / np.linalg.norm(verts, axis=1, keepdims=True), faces


def _subdivide(verts: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Split each triangle into four at its edge midpoints (pushed back onto the unit sphere);
    the corner order of every new triangle follows its parent, so the winding is kept."""
    edges = faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2)
    uniq, inverse = np.unique(np.sort(edges, axis=1), axis=0, return_inverse=True)
    mid = verts[uniq].mean(axis=1)
    mid /= np.linalg.norm(mid, axis=1, keepdims=True)
    m = len(verts) + inverse.reshape(-1, 3)       # midpoints of edges 01, 12, 20
    a, b, c = faces.T
    ab, bc, ca = m.T
    new = np.stack([np.stack([a, ab, ca], 1), np.stack([ab, b, bc], 1),
                    np.stack([ca, bc, c], 1), np.stack([ab, bc, ca], 1)], axis=1)
    return np.concatenate([verts, mid]), new.reshape(-1, 3)


def icosphere(radius: float = 1.0, subdivisions: int = 2) -> TriMesh:
    """Geodesic sphere (no latitude-longitude poles) of 20 * 4**subdivisions triangles, m."""
    _positive(radius=radius)
    if subdivisions < 0:
        raise ValueError(f'subdivisions must be >= 0, got {subdivisions}')
    verts, faces = _icosahedron()
    for _ in range(int(subdivisions)):
        verts, faces = _subdivide(verts, faces)
    return TriMesh(radius * verts, faces)


def ellipsoid(a: float, b: float, c: float, subdivisions: int = 2) -> TriMesh:
    """Ellipsoid with semi-axes a, b, c (m) along x, y, z: a scaled unit icosphere (a positive
    diagonal scaling keeps the winding outward)."""
    _positive(a=a, b=b, c=c)
    unit = icosphere(1.0, subdivisions)
    return TriMesh(unit.vertices * np.array([a, b, c]), unit.faces)
