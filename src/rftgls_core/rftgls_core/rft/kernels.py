"""Fused Agarwal 3D-RFT wrench kernels (numba): one pass over twists x facets, no temporaries.

Same arithmetic as `agarwal._PreparedAgarwal.stress` + `engine.BuriedBody` (the numpy path is
the reference; tests hold the two together to 1e-12). numpy needs ~130 array passes per
pair and is bound by memory traffic; the fused loop keeps everything in registers.
If numba is missing, `AVAILABLE` is False and the engine uses numpy.
"""
from __future__ import annotations

import math

import numpy as np

try:
    import numba
    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only on machines without numba
    numba = None
    AVAILABLE = False

LEADING_TOL = 1e-12


def _jit(fn):
    if not AVAILABLE:
        return fn
    return numba.njit(cache=True, fastmath=False, nogil=True)(fn)


@_jit
def _facet_stress(ux, uy, uz, nx, ny, nz, ndx, ndy, ndz, poly, f, xi, mu):
    """alpha (N/m^3) of facet f for unit velocity direction u; poly (F, 30) cubic coefficients."""
    x1 = -uz
    x3 = ndx * ux + ndy * uy + ndz * uz
    x1s = x1 * x1
    x3s = x3 * x3
    # Monomial order of agarwal._MONOMIALS: (a, c) for a in 0..3, c in 0..3-a.
    m1 = x3
    m2 = x3s
    m3 = x3s * x3
    m4 = x1
    m5 = x1 * x3
    m6 = x1 * x3s
    m7 = x1s
    m8 = x1s * x3
    m9 = x1s * x1
    fj0 = 0.0
    fj1 = 0.0
    fj2 = 0.0
    for j in range(3):
        b = 10 * j
        val = (poly[f, b] + poly[f, b + 1] * m1 + poly[f, b + 2] * m2 + poly[f, b + 3] * m3
               + poly[f, b + 4] * m4 + poly[f, b + 5] * m5 + poly[f, b + 6] * m6
               + poly[f, b + 7] * m7 + poly[f, b + 8] * m8 + poly[f, b + 9] * m9)
        if j == 0:
            fj0 = val
        elif j == 1:
            fj1 = val
        else:
            fj2 = val
    ax = fj0 * ndx + fj1 * ux
    ay = fj0 * ndy + fj1 * uy
    az = fj0 * ndz + fj1 * uz - fj2
    if mu < math.inf:
        an = ax * nx + ay * ny + az * nz
        tx = ax - an * nx
        ty = ay - an * ny
        tz = az - an * nz
        tn = math.sqrt(tx * tx + ty * ty + tz * tz)
        lim = mu * abs(an)
        s = 1.0
        if tn > lim:
            s = lim / tn
        ax = an * nx + s * tx
        ay = an * ny + s * ty
        az = an * nz + s * tz
    return xi * ax, xi * ay, xi * az


@_jit
def planar_wrench(twists, r, n, nd, poly, w, xi, mu, out):
    """(Fx, Fz, My) per planar twist (vx, vz, wy); r = facet centroid - ref; w = area*depth."""
    nf = r.shape[0]
    for m in range(twists.shape[0]):
        vx0 = twists[m, 0]
        vz0 = twists[m, 1]
        wy = twists[m, 2]
        smax = 0.0
        for f in range(nf):
            vx = vx0 + wy * r[f, 2]
            vz = vz0 - wy * r[f, 0]
            s = math.sqrt(vx * vx + vz * vz)
            if s > smax:
                smax = s
        tol = 1e-12 * max(smax, 1e-300)
        fx = 0.0
        fz = 0.0
        my = 0.0
        for f in range(nf):
            vx = vx0 + wy * r[f, 2]
            vz = vz0 - wy * r[f, 0]
            s = math.sqrt(vx * vx + vz * vz)
            if s <= tol:
                continue
            ux = vx / s
            uz = vz / s
            if ux * n[f, 0] + uz * n[f, 2] < -LEADING_TOL:
                continue
            ax, ay, az = _facet_stress(ux, 0.0, uz, n[f, 0], n[f, 1], n[f, 2],
                                       nd[f, 0], nd[f, 1], nd[f, 2], poly, f, xi, mu)
            fx += w[f] * ax
            fz += w[f] * az
            my += w[f] * (r[f, 2] * ax - r[f, 0] * az)
        out[m, 0] = fx
        out[m, 1] = fz
        out[m, 2] = my


@_jit
def spatial_wrench(twists, r, n, nd, poly, w, xi, mu, out):
    """(Fx, Fy, Fz, Mx, My, Mz) per spatial twist (vx, vy, vz, wx, wy, wz)."""
    nf = r.shape[0]
    for m in range(twists.shape[0]):
        v0x, v0y, v0z = twists[m, 0], twists[m, 1], twists[m, 2]
        wx, wy, wz = twists[m, 3], twists[m, 4], twists[m, 5]
        smax = 0.0
        for f in range(nf):
            vx = v0x + wy * r[f, 2] - wz * r[f, 1]
            vy = v0y + wz * r[f, 0] - wx * r[f, 2]
            vz = v0z + wx * r[f, 1] - wy * r[f, 0]
            s = math.sqrt(vx * vx + vy * vy + vz * vz)
            if s > smax:
                smax = s
        tol = 1e-12 * max(smax, 1e-300)
        acc = np.zeros(6)
        for f in range(nf):
            vx = v0x + wy * r[f, 2] - wz * r[f, 1]
            vy = v0y + wz * r[f, 0] - wx * r[f, 2]
            vz = v0z + wx * r[f, 1] - wy * r[f, 0]
            s = math.sqrt(vx * vx + vy * vy + vz * vz)
            if s <= tol:
                continue
            ux = vx / s
            uy = vy / s
            uz = vz / s
            if ux * n[f, 0] + uy * n[f, 1] + uz * n[f, 2] < -LEADING_TOL:
                continue
            ax, ay, az = _facet_stress(ux, uy, uz, n[f, 0], n[f, 1], n[f, 2],
                                       nd[f, 0], nd[f, 1], nd[f, 2], poly, f, xi, mu)
            fx = w[f] * ax
            fy = w[f] * ay
            fz = w[f] * az
            acc[0] += fx
            acc[1] += fy
            acc[2] += fz
            acc[3] += r[f, 1] * fz - r[f, 2] * fy
            acc[4] += r[f, 2] * fx - r[f, 0] * fz
            acc[5] += r[f, 0] * fy - r[f, 1] * fx
        for k in range(6):
            out[m, k] = acc[k]
