"""Small scalar kernels of a warm step, compiled by numba when it is installed.

A warm step (surfaces/warm.py) handles a few dozen triangles and a handful of twists, where
numpy's per-call overhead is most of the time; these loops do the same arithmetic in the same
order as the numpy reference versions (warm_newton.py, warm_guards.py, newton.py, closure.py),
which stay the fallback on a machine without numba (`HAVE_NUMBA`).
"""
from __future__ import annotations

import math

import numpy as np

try:
    import numba
except ImportError:  # pragma: no cover - machines without numba run the plain Python loops
    numba = None  # type: ignore[assignment]

HAVE_NUMBA = numba is not None


def unit_rows_over(ts, diag):
    """newton.unit_rows(ts / diag) for ts (M, 3): the same operations in the same order."""
    out = np.empty_like(ts)
    for i in range(ts.shape[0]):
        x0, x1, x2 = ts[i, 0] / diag[0], ts[i, 1] / diag[1], ts[i, 2] / diag[2]
        n = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if not n > 0.0:
            n = 1.0
        out[i, 0], out[i, 1], out[i, 2] = x0 / n, x1 / n, x2 / n
    return out


def point_triangle(ax, ay, az, bx, by, bz, cx, cy, cz):
    """Distance from the origin to the triangle (a, b, c), as _distances does it."""
    e1x, e1y, e1z = bx - ax, by - ay, bz - az
    e2x, e2y, e2z = cx - ax, cy - ay, cz - az
    nx, ny, nz = e1y * e2z - e1z * e2y, e1z * e2x - e1x * e2z, e1x * e2y - e1y * e2x
    nn = nx * nx + ny * ny + nz * nz
    s1 = (ay * bz - az * by) * nx + (az * bx - ax * bz) * ny + (ax * by - ay * bx) * nz
    s2 = (by * cz - bz * cy) * nx + (bz * cx - bx * cz) * ny + (bx * cy - by * cx) * nz
    s3 = (cy * az - cz * ay) * nx + (cz * ax - cx * az) * ny + (cx * ay - cy * ax) * nz
    if s1 >= 0.0 and s2 >= 0.0 and s3 >= 0.0 and nn > 0.0:
        return abs(nx * ax + ny * ay + nz * az) / math.sqrt(nn)
    best = math.inf
    for ux, uy, uz, vx, vy, vz in ((ax, ay, az, bx, by, bz), (bx, by, bz, cx, cy, cz),
                                   (cx, cy, cz, ax, ay, az)):
        ex, ey, ez = vx - ux, vy - uy, vz - uz
        ee = max(ex * ex + ey * ey + ez * ez, 1e-300)
        t = min(max(-(ux * ex + uy * ey + uz * ez) / ee, 0.0), 1.0)
        px, py, pz = ux + t * ex, uy + t * ey, uz + t * ez
        best = min(best, math.sqrt(px * px + py * py + pz * pz))
    return best


def clearance_bounds(ws, faces, px, py, pz):
    """(upper, lower) of warm_guards.triangle_clearance for every face (F, 3) of ws (V, 3):
    the distance from (px, py, pz) to the face's nearest vertex, and that less the face's
    longest edge / sqrt(3) (the numpy reference's operations in its order; NaN propagates as
    numpy's min and max propagate it)."""
    n = faces.shape[0]
    upper = np.empty(n)
    lower = np.empty(n)
    r3 = math.sqrt(3.0)
    for k in range(n):
        near = math.inf
        edge = -math.inf
        for c in range(3):
            i, j = faces[k, c], faces[k, c - 1]
            dx, dy, dz = ws[i, 0] - px, ws[i, 1] - py, ws[i, 2] - pz
            r = math.sqrt(dx * dx + dy * dy + dz * dz)
            if not r >= near and near == near:   # r nearer, or r NaN (kept once NaN)
                near = r
            ex, ey, ez = ws[i, 0] - ws[j, 0], ws[i, 1] - ws[j, 1], ws[i, 2] - ws[j, 2]
            e = math.sqrt(ex * ex + ey * ey + ez * ez)
            if not e <= edge and edge == edge:
                edge = e
        upper[k] = near
        lower[k] = near - edge / r3
    return upper, lower


def guard_use_loop(wg, w0, tri, points, slack, clearance, swing):
    """(largest closed-in fraction of a guard triangle's clearance, median guard motion)."""
    closed = -math.inf
    for k in range(tri.shape[0]):
        i, j, m = tri[k, 0], tri[k, 1], tri[k, 2]
        px, py, pz = points[k, 0], points[k, 1], points[k, 2]
        dist = point_triangle(wg[i, 0] - px, wg[i, 1] - py, wg[i, 2] - pz,
                               wg[j, 0] - px, wg[j, 1] - py, wg[j, 2] - pz,
                               wg[m, 0] - px, wg[m, 1] - py, wg[m, 2] - pz)
        closed = max(closed, (clearance[k] - (dist - slack[k] - swing)) / clearance[k])
    motion = np.empty(wg.shape[0])
    for k in range(wg.shape[0]):
        dx, dy, dz = wg[k, 0] - w0[k, 0], wg[k, 1] - w0[k, 1], wg[k, 2] - w0[k, 2]
        motion[k] = math.sqrt(dx * dx + dy * dy + dz * dz)
    return closed, np.median(motion)


def ray_hits_loop(wg, patch, d, bary_tol=1e-9, dist_rtol=1e-9):
    """ray_hits on the triangles `patch` of `wg`: (distinct crossings, first s, its face,
    and the crossing's coordinates u, v along the face's edges to its second and third
    vertex, as raycast's)."""
    n = patch.shape[0]
    s_all = np.empty(n)
    u_all = np.empty(n)
    v_all = np.empty(n)
    face = np.empty(n, dtype=np.int64)
    h = 0
    scale = 0.0
    for k in range(n):
        for c in range(3):
            for q in range(3):
                scale = max(scale, abs(wg[patch[k, c], q]))
    dx, dy, dz = d[0], d[1], d[2]
    for k in range(n):
        a, b, c = patch[k, 0], patch[k, 1], patch[k, 2]
        v0x, v0y, v0z = wg[a, 0], wg[a, 1], wg[a, 2]
        e1x, e1y, e1z = wg[b, 0] - v0x, wg[b, 1] - v0y, wg[b, 2] - v0z
        e2x, e2y, e2z = wg[c, 0] - v0x, wg[c, 1] - v0y, wg[c, 2] - v0z
        # n_det = e2 x e1, det = n_det . d
        det = (e2y * e1z - e2z * e1y) * dx + (e2z * e1x - e2x * e1z) * dy \
            + (e2x * e1y - e2y * e1x) * dz
        tol = 1e-12 * math.sqrt(e1x * e1x + e1y * e1y + e1z * e1z) \
            * math.sqrt(e2x * e2x + e2y * e2y + e2z * e2z)
        if not abs(det) > tol:
            continue
        inv = 1.0 / det
        q0x, q0y, q0z = -v0x, -v0y, -v0z
        u = ((e2y * q0z - e2z * q0y) * dx + (e2z * q0x - e2x * q0z) * dy
             + (e2x * q0y - e2y * q0x) * dz) * inv
        qx, qy, qz = q0y * e1z - q0z * e1y, q0z * e1x - q0x * e1z, q0x * e1y - q0y * e1x
        v = (qx * dx + qy * dy + qz * dz) * inv
        s = (e2x * qx + e2y * qy + e2z * qz) * inv
        if u >= -bary_tol and v >= -bary_tol and u + v <= 1.0 + bary_tol and s > 0.0:
            s_all[h], u_all[h], v_all[h] = s, u, v
            face[h] = k
            h += 1
    if h == 0:
        return 0, math.inf, -1, math.nan, math.nan
    order = np.argsort(s_all[:h])
    count = 1
    for i in range(1, h):
        if s_all[order[i]] - s_all[order[i - 1]] > dist_rtol * max(scale, 1e-300):
            count += 1
    i = order[0]
    return count, s_all[i], face[i], u_all[i], v_all[i]


def patch_twists(t, cu, cv):
    """closure.local_patches(t) for a unit twist t (3,): the twists t + cu u + cv v, unit,
    with (u, v) the tangent basis of newton._tangent_basis (the same operations per row;
    numpy's 3-vector calls cost more than the 243 rows)."""
    n = math.sqrt(t[0] * t[0] + t[1] * t[1] + t[2] * t[2])
    tx, ty, tz = t[0] / n, t[1] / n, t[2] / n
    m = 0   # first smallest |component|, as np.argmin
    if abs(ty) < abs(tx):
        m = 1
    if abs(tz) < (abs(ty) if m == 1 else abs(tx)):
        m = 2
    hx, hy, hz = (1.0, 0.0, 0.0) if m == 0 else ((0.0, 1.0, 0.0) if m == 1 else (0.0, 0.0, 1.0))
    ux, uy, uz = ty * hz - tz * hy, tz * hx - tx * hz, tx * hy - ty * hx
    n = math.sqrt(ux * ux + uy * uy + uz * uz)
    ux, uy, uz = ux / n, uy / n, uz / n
    vx, vy, vz = ty * uz - tz * uy, tz * ux - tx * uz, tx * uy - ty * ux
    out = np.empty((cu.shape[0], 3))
    for i in range(cu.shape[0]):
        px = tx + cu[i] * ux + cv[i] * vx
        py = ty + cu[i] * uy + cv[i] * vy
        pz = tz + cu[i] * uz + cv[i] * vz
        n = math.sqrt(px * px + py * py + pz * pz)
        out[i, 0], out[i, 1], out[i, 2] = px / n, py / n, pz / n
    return out


def newton_batch_twists(t, h):
    """The twists of one Newton iteration (newton_on_sphere's batch: the points, then their
    forward differences along u, then along v) and the tangent bases (u, v)."""
    k = t.shape[0]
    u = np.empty((k, 3))
    v = np.empty((k, 3))
    batch = np.empty((3 * k, 3))
    for i in range(k):
        tx, ty, tz = t[i, 0], t[i, 1], t[i, 2]
        m = 0   # first smallest |component|, as np.argmin
        if abs(ty) < abs(tx):
            m = 1
        if abs(tz) < (abs(ty) if m == 1 else abs(tx)):
            m = 2
        hx, hy, hz = (1.0, 0.0, 0.0) if m == 0 else ((0.0, 1.0, 0.0) if m == 1
                                                       else (0.0, 0.0, 1.0))
        ux, uy, uz = ty * hz - tz * hy, tz * hx - tx * hz, tx * hy - ty * hx
        n = math.sqrt(ux * ux + uy * uy + uz * uz)
        ux, uy, uz = ux / n, uy / n, uz / n
        vx, vy, vz = ty * uz - tz * uy, tz * ux - tx * uz, tx * uy - ty * ux
        u[i, 0], u[i, 1], u[i, 2] = ux, uy, uz
        v[i, 0], v[i, 1], v[i, 2] = vx, vy, vz
        batch[i, 0], batch[i, 1], batch[i, 2] = tx, ty, tz
        for j, (ex, ey, ez) in enumerate(((ux, uy, uz), (vx, vy, vz))):
            px, py, pz = tx + h * ex, ty + h * ey, tz + h * ez
            n = math.sqrt(px * px + py * py + pz * pz)
            row = (j + 1) * k + i
            batch[row, 0], batch[row, 1], batch[row, 2] = px / n, py / n, pz / n
    return batch, u, v


def newton_update(t, u, v, w, d, h, rtol, best_t, best_r, best_step, bu, bv, lam, jac, s,
                   conv):
    """One newton_on_sphere iteration after its wrench call, in place; the next twists go
    into t. True when every seed converged or gave up (the reference's two breaks)."""
    k = t.shape[0]
    e1x, e1y = -d[1], d[0]
    r0 = np.empty(k)
    r1 = np.empty(k)
    improved = np.zeros(k, dtype=np.bool_)
    all_conv = True
    for i in range(k):
        w0x, w0y, w0z = w[i, 0], w[i, 1], w[i, 2]
        ra, rb = e1x * w0x + e1y * w0y, w0z
        r0[i], r1[i] = ra, rb
        rn = math.sqrt(ra * ra + rb * rb)
        if rn < best_r[i]:
            improved[i] = True
            best_r[i] = rn
            best_t[i, 0], best_t[i, 1], best_t[i, 2] = t[i, 0], t[i, 1], t[i, 2]
            a1 = (w[k + i, 0] - w0x, w[k + i, 1] - w0y, w[k + i, 2] - w0z)
            a2 = (w[2 * k + i, 0] - w0x, w[2 * k + i, 1] - w0y, w[2 * k + i, 2] - w0z)
            jac[i, 0, 0] = (e1x * a1[0] + e1y * a1[1]) / h
            jac[i, 1, 0] = a1[2] / h
            jac[i, 0, 1] = (e1x * a2[0] + e1y * a2[1]) / h
            jac[i, 1, 1] = a2[2] / h
            s[i] = d[0] * w0x + d[1] * w0y + d[2] * w0z
        conv[i] = best_r[i] <= rtol * max(abs(s[i]), 1e-3)
        if not conv[i]:
            all_conv = False
    if all_conv:
        return True
    done = True
    for i in range(k):
        if conv[i]:
            t[i, 0], t[i, 1], t[i, 2] = best_t[i, 0], best_t[i, 1], best_t[i, 2]
            continue
        if improved[i]:
            j00, j01, j10, j11 = jac[i, 0, 0], jac[i, 0, 1], jac[i, 1, 0], jac[i, 1, 1]
            det = j00 * j11 - j01 * j10
            if det != 0.0:
                sa = -(j11 * r0[i] - j01 * r1[i]) / det
                sb = -(-j10 * r0[i] + j00 * r1[i]) / det
            else:
                # rank <= 1: the pseudo-inverse is J^T / |J|_F^2 (0 for J = 0)
                f2 = j00 * j00 + j01 * j01 + j10 * j10 + j11 * j11
                f2 = f2 if f2 > 0.0 else math.inf
                sa = -(j00 * r0[i] + j10 * r1[i]) / f2
                sb = -(j01 * r0[i] + j11 * r1[i]) / f2
            nrm = math.sqrt(sa * sa + sb * sb)
            sc = min(1.0, 0.3 / max(nrm, 1e-300))    # trust region, rad
            best_step[i, 0], best_step[i, 1] = sa * sc, sb * sc
            for c in range(3):
                bu[i, c], bv[i, c] = u[i, c], v[i, c]
            lam[i] = 1.0
        else:
            lam[i] *= 0.5
        fa, fb = lam[i] * best_step[i, 0], lam[i] * best_step[i, 1]
        px = best_t[i, 0] + fa * bu[i, 0] + fb * bv[i, 0]
        py = best_t[i, 1] + fa * bu[i, 1] + fb * bv[i, 1]
        pz = best_t[i, 2] + fa * bu[i, 2] + fb * bv[i, 2]
        n = math.sqrt(px * px + py * py + pz * pz)
        t[i, 0], t[i, 1], t[i, 2] = px / n, py / n, pz / n
        if not lam[i] < 1e-6:
            done = False
    return done


if numba is not None:
    _jit = numba.njit(cache=True, nogil=True)
    point_triangle = _jit(point_triangle)
    clearance_bounds = _jit(clearance_bounds)
    guard_use_loop = _jit(guard_use_loop)
    ray_hits_loop = _jit(ray_hits_loop)
    newton_batch_twists = _jit(newton_batch_twists)
    patch_twists = _jit(patch_twists)
    newton_update = _jit(newton_update)
    unit_rows_over = _jit(unit_rows_over)
