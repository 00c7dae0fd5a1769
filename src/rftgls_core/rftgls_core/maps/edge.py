"""Information from inside support-edge cells: the per-node support margin (schema 2 maps).

The capacity along d(phi) does not fall to zero at the support edge, it stops
(docs/design/maps.md): what ends is the origin of W_ext space (zero external load: the
robot's weight alone) lying inside the limit surface, and that happens in another load
direction. The
support margin is a continuous quantity whose zero is that edge, so the map can interpolate it
inside a cell whose corners disagree on support:

    margin = +dist(origin, surface) where the legs hold the weight, -dist where they do not,

in the scaled metric (dimensionless), signed by the node's own status. The build computes it
on the map's twist sphere (n_twists) and, at the corners of cells that straddle the support
edge (the only place the rule reads it), again on the dense sphere of the weight-held check
(EDGE_MARGIN_TWISTS), together with its gradient. It also bounds the capacity from below:
the first exit of the load ray lies at least the origin's distance from the surface away, and
d(phi) has no moment part, so capacity_N >= s_F margin.

The margin is not linear across a cell (the coarse grid's cells span margins of -1.2 .. +1.0
next to a zero crossing), so each node also stores its gradient along the four state axes
(central differences at a quarter of the smaller neighbouring cell, one-sided at the grid's
ends), and the map interpolates the corners' first-order Taylor predictions (query.py).
Measured on MiniRQuad (300 random states): with the plain multilinear margin the states that
hold and those that do not overlap over margins 0 .. 0.12, with the Taylor blend only 5 of 49
edge states that hold fall below the largest margin of a state that does not.
"""
from __future__ import annotations

import numpy as np

from ..predictor.live import RobotPredictor
from ..surfaces.base import SUPPORT_CHECK_TWISTS, LimitSurface
from ..surfaces.mesh_loops import HAVE_NUMBA, as_mesh, mesh_distance
from ..surfaces.raycast import winding_number
from ..surfaces.twist_sphere import TwistSphere
from ..types import AnchorState, Pull
from .grid import MapGrid

# Finite-difference step of the margin gradient, as a share of the smaller neighbouring cell.
GRAD_STEP = 0.25
# Twists of the sphere the margin and its gradient are computed on at the corners of edge
# cells (the only place the rule reads them): that of the weight-held check, whose answer the
# node statuses carry. The map's own 1000-twist mesh is too coarse there: over 6 x 300 random
# MiniRQuad states in edge cells, states that cannot hold the weight had margins of up to 0.21
# on it and at most 0.027 on 8,000 twists, while every state that holds had >= 0 on 8,000.
# The gradient is taken on the same sphere: with 1,000-twist gradients the build took 74 s
# instead of 335 s but MiniRQuad seed 1 fell from 95.6 to 94.4 % (maps/README.md).
EDGE_MARGIN_TWISTS = SUPPORT_CHECK_TWISTS


def point_mesh_distance(vertices: np.ndarray, faces: np.ndarray,
                        point: np.ndarray | None = None) -> float:
    """Euclidean distance from `point` (default origin) to a triangle mesh: per triangle the
    closest point in its plane when it projects inside, else on an edge. One compiled loop
    (surfaces/mesh_loops.py) with numba, else point_mesh_distance_numpy (the same numbers)."""
    if not HAVE_NUMBA:
        return point_mesh_distance_numpy(vertices, faces, point)
    p = (0.0, 0.0, 0.0) if point is None else tuple(float(x) for x in point)
    return float(mesh_distance(*as_mesh(vertices, faces), *p))


def point_mesh_distance_numpy(vertices: np.ndarray, faces: np.ndarray,
                              point: np.ndarray | None = None) -> float:
    """point_mesh_distance as numpy expressions vectorised over the triangles (the
    reference of the compiled loop)."""
    p = np.zeros(3) if point is None else np.asarray(point, dtype=float)
    v = np.asarray(vertices, dtype=float) - p
    f = np.asarray(faces, dtype=np.intp)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    e0, e1 = b - a, c - a
    n = np.cross(e0, e1)
    nn = np.einsum('ij,ij->i', n, n)
    ok = nn > 0.0
    # Projection of the point (origin after the shift) onto each plane, barycentric coords.
    t = np.where(ok, np.einsum('ij,ij->i', a, n) / np.where(ok, nn, 1.0), 0.0)
    q = t[:, None] * n                     # closest point of the plane to the origin
    d00 = np.einsum('ij,ij->i', e0, e0)
    d01 = np.einsum('ij,ij->i', e0, e1)
    d11 = np.einsum('ij,ij->i', e1, e1)
    r = q - a
    d20 = np.einsum('ij,ij->i', r, e0)
    d21 = np.einsum('ij,ij->i', r, e1)
    den = d00 * d11 - d01 * d01
    good = ok & (den > 0.0)
    den = np.where(good, den, 1.0)
    bv = (d11 * d20 - d01 * d21) / den
    bw = (d00 * d21 - d01 * d20) / den
    inside = good & (bv >= 0.0) & (bw >= 0.0) & (bv + bw <= 1.0)
    plane = np.where(inside, np.abs(t) * np.sqrt(np.where(ok, nn, 0.0)), np.inf)

    def seg(x: np.ndarray, y: np.ndarray) -> np.ndarray:
        e = y - x
        ee = np.einsum('ij,ij->i', e, e)
        s = np.clip(-np.einsum('ij,ij->i', x, e) / np.where(ee > 0.0, ee, 1.0), 0.0, 1.0)
        return np.linalg.norm(x + s[:, None] * e, axis=1)

    edge = np.minimum(np.minimum(seg(a, b), seg(b, c)), seg(c, a))
    return float(np.min(np.minimum(plane, edge))) if len(f) else float('inf')


def node_support_margin(predictor: RobotPredictor, sphere: TwistSphere, state: AnchorState,
                        pull: Pull | str, held: bool | None = None) -> float:
    """Support margin of one state and pull (see the module doc); `held` is the node's status
    (a value at its pull angles), None: the winding number of the sphere mesh decides. NaN
    when the pose has no surface (no buried leg, or wrenches that are not finite)."""
    anchor = predictor.pose(state, pull)
    if anchor.body.facets_active == 0:
        return float('nan')
    problem = anchor.problem
    w = problem.wrench_fn(sphere.twists_raw(problem.scaling))
    if not np.all(np.isfinite(w)):
        return float('nan')
    return signed_margin(problem.scaling.wrench_to_scaled(w), sphere, held)


def signed_margin(ws: np.ndarray, sphere: TwistSphere, held: bool | None = None) -> float:
    """The support margin from the scaled wrenches ws of the twists of `sphere` (see
    node_support_margin)."""
    dist = point_mesh_distance(ws, sphere.faces)
    if held is None:
        held = abs(winding_number(ws, sphere.faces)) >= 0.5
    return dist if held else -dist


def fitted_wrenches(surface: LimitSurface | None, sphere: TwistSphere,
                    support_check: bool = False) -> np.ndarray | None:
    """The scaled wrenches a fit evaluated on `sphere` (the same numbers node_support_margin
    would compute again for that pose), or None when it evaluated none there. support_check:
    those of the fit's dense support check (surfaces/base.py) instead of its own sphere's."""
    if surface is None:
        return None
    cloud = surface.support_samples_ if support_check else surface.cloud_
    return cloud[1] if cloud is not None and cloud[0] is sphere else None


def node_margin_gradient(predictor: RobotPredictor, sphere: TwistSphere, grid: MapGrid, k: int,
                         pull: Pull | str) -> np.ndarray:
    """(4,) d margin / d (h [1/m], theta_b, theta_l1, theta_l2 [1/rad]) at flat state index
    k: central differences at GRAD_STEP of the smaller neighbouring cell, one-sided at the
    grid's ends; NaN where a sample has no surface."""
    idx = np.unravel_index(int(k), grid.state_shape)
    x0 = np.array([float(a[i]) for a, i in zip(grid.axes, idx)])
    out = np.full(4, np.nan)
    for a, (ax, i) in enumerate(zip(grid.axes, idx)):
        below = ax[i] - ax[i - 1] if i > 0 else np.inf
        above = ax[i + 1] - ax[i] if i + 1 < len(ax) else np.inf
        step = GRAD_STEP * min(below, above)
        lo, hi = x0.copy(), x0.copy()
        lo[a] = max(ax[0], x0[a] - step)
        hi[a] = min(ax[-1], x0[a] + step)
        m_lo = node_support_margin(predictor, sphere, AnchorState(*map(float, lo)), pull)
        m_hi = node_support_margin(predictor, sphere, AnchorState(*map(float, hi)), pull)
        out[a] = (m_hi - m_lo) / (hi[a] - lo[a])
    return out
