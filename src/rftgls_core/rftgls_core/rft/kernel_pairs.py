"""The arithmetic of the fused RFT kernels (rft/kernels.py): one facet-twist pair, and a block
of twists against every facet. All numba, inlined into the kernels.

Per facet, a block's twist loop runs as three short loops through small arrays in L1
(`_spatial_pass`, `_planar_pass`): direction, weight and x3; the three cubics; the friction cap
and the sums. As one long loop body the dependency chain of a pair (two square roots, two
divisions, the cubics) was ~200 cycles, more than the CPU's reorder window overlaps from one
iteration to the next, and the kernel ran at a third of the machine's multiply-add peak.

Rest: a facet rests (no direction, no force) when its speed is at most REST_TOL times the
fastest facet's. That needs the fastest speed before the pass; `_twist_bounds` brackets the
tolerance between lo and hi from a pass over the facets instead of the pairs, and says when
no facet can be that slow at all (then the pass skips the test). A facet between lo and hi
makes the pass report its block ambiguous, and the block runs again with the exact tolerance
(`_exact_tolerances`): never on real bodies, it takes a facet within 1e-12 of resting.
"""
from __future__ import annotations

import math

import numpy as np

try:
    import numba
    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only on machines without numba
    numba = None  # type: ignore[assignment]
    AVAILABLE = False

_FASTMATH = {'contract'}


def _jit(parallel: bool = False, inline: bool = False):
    def wrap(fn):
        if not AVAILABLE:
            return fn
        kw = dict(cache=True, fastmath=_FASTMATH, nogil=True, error_model='numpy')
        if parallel:
            kw['parallel'] = True
        if inline:
            kw['inline'] = 'always'
        return numba.njit(**kw)(fn)
    return wrap


@_jit(inline=True)
def _cubic(q, o, x1, x3, x3s):
    """sum over the monomials x1^a x3^c (a + c <= 3, agarwal._MONOMIALS order) of
    q[o + m] x1^a x3^c, as a tree of nine multiply-adds four deep (a left-to-right sum is
    nine deep, and the loop's speed is bound by that depth)."""
    c0 = (q[o] + q[o + 1] * x3) + (q[o + 2] + q[o + 3] * x3) * x3s
    c1 = (q[o + 4] + q[o + 5] * x3) + q[o + 6] * x3s
    c2 = (q[o + 7] + q[o + 8] * x3) + q[o + 9] * x1
    return c0 + (c1 + c2 * x1) * x1


@_jit(inline=True)
def _cubics(x3, uz, p):
    """(f1, f2, f3) of one facet (ten-per-f_j cubic coefficients p) for x1 = -u.z and
    x3 = n_d . u."""
    x1 = -uz
    x3s = x3 * x3
    return _cubic(p, 0, x1, x3, x3s), _cubic(p, 10, x1, x3, x3s), _cubic(p, 20, x1, x3, x3s)


@_jit(inline=True)
def _cap(ax, ay, az, nx, ny, nz, mu, one):
    """The surface-friction cap: tangential stress at most mu x |normal stress|."""
    an = ax * nx + ay * ny + az * nz
    tx = ax - an * nx
    ty = ay - an * ny
    tz = az - an * nz
    tn = math.sqrt(tx * tx + ty * ty + tz * tz)
    lim = mu * abs(an)
    s = lim / tn if tn > lim else one
    return an * nx + s * tx, an * ny + s * ty, an * nz + s * tz


@_jit(inline=True)
def _coefficients(poly, f):
    """Row f of poly (F, 30) as a tuple: scalars the compiler keeps in registers across the
    twist loop (an array row would be reloaded there for fear of aliasing the accumulators)."""
    q = poly[f]
    return (q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7], q[8], q[9], q[10], q[11], q[12], q[13],
            q[14], q[15], q[16], q[17], q[18], q[19], q[20], q[21], q[22], q[23], q[24], q[25],
            q[26], q[27], q[28], q[29])


@_jit(inline=True)
def _side(nx, ny, nz, ndx, ndy, ndz, one):
    """+1 when n_d is n, -1 when it is -n (agarwal.downward_normal gives one or the other)."""
    return one if (ndx == nx and ndy == ny and ndz == nz) else -one


@_jit(inline=True)
def _spatial_speed2(tw, i, rx, ry, rz):
    """Velocity and squared speed of twist column i of tw (6, nb) at the point r."""
    vx = tw[0, i] + tw[4, i] * rz - tw[5, i] * ry
    vy = tw[1, i] + tw[5, i] * rx - tw[3, i] * rz
    vz = tw[2, i] + tw[3, i] * ry - tw[4, i] * rx
    return vx, vy, vz, vx * vx + vy * vy + vz * vz


@_jit(inline=True)
def _planar_speed2(tw, i, rx, rz):
    """In-plane velocity and squared speed of planar twist column i of tw (3, nb) at (rx, rz)."""
    vx = tw[0, i] + tw[2, i] * rz
    vz = tw[1, i] - tw[2, i] * rx
    return vx, vz, vx * vx + vz * vz


@_jit(inline=True)
def _rest_tolerance(s2max, rest_tol, tiny):
    """rest_tol x the fastest speed (s2max: its square; floored at the dtype's tiny). sqrt is
    monotone and correctly rounded, so this is rest_tol x the largest computed speed."""
    return rest_tol * max(math.sqrt(s2max), tiny)


@_jit(inline=True)
def _extent(planar, r):
    """(max |r|, x0, x1, z0, z1) of the facet points r (F >= 1, planar: |r| in x-z): how far
    the facets reach from the reference point, and their box in x and z."""
    rmax2 = r.dtype.type(0)
    x0, x1, z0, z1 = r[0, 0], r[0, 0], r[0, 2], r[0, 2]
    for f in range(r.shape[0]):
        rx, ry, rz = r[f, 0], r[f, 1], r[f, 2]
        rmax2 = max(rmax2, rx * rx + rz * rz if planar else rx * rx + ry * ry + rz * rz)
        x0, x1, z0, z1 = min(x0, rx), max(x1, rx), min(z0, rz), max(z1, rz)
    return math.sqrt(rmax2), x0, x1, z0, z1


@_jit(inline=True)
def _twist_bounds(planar, tw, i, r, rmax, x0, x1, z0, z1, rest_tol, margin):
    """(lo, hi, moves) of twist column i of tw: lo <= its rest tolerance <= hi, and whether
    every facet certainly moves.

    hi: rest_tol (|v| + |w| max|r|) x margin (the fastest facet is no faster). lo: the exact
    formula on four of the facets (the fastest is no slower). moves: a lower bound of every
    facet's speed clears hi by more than the rounding of a computed speed (16 eps (|v| + |w|
    max|r|)); for a spatial twist the bound is its pitch speed |v . w| / |w| (the velocity's
    part along w is the same at every point), for a planar one |w_y| times the distance from
    its instantaneous centre to the facets' box.
    """
    tiny = np.finfo(tw.dtype).tiny
    eps = np.finfo(tw.dtype).eps
    zero = tw.dtype.type(0)
    nf = r.shape[0]
    if planar:
        v2 = tw[0, i] * tw[0, i] + tw[1, i] * tw[1, i]
        w2 = tw[2, i] * tw[2, i]
    else:
        v2 = tw[0, i] * tw[0, i] + tw[1, i] * tw[1, i] + tw[2, i] * tw[2, i]
        w2 = tw[3, i] * tw[3, i] + tw[4, i] * tw[4, i] + tw[5, i] * tw[5, i]
    scale = math.sqrt(v2) + math.sqrt(w2) * rmax
    hi = rest_tol * max(margin * scale, tiny)
    s2 = zero
    for f in (0, nf // 3, (2 * nf) // 3, nf - 1):
        if planar:
            s2 = max(s2, _planar_speed2(tw, i, r[f, 0], r[f, 2])[2])
        else:
            s2 = max(s2, _spatial_speed2(tw, i, r[f, 0], r[f, 1], r[f, 2])[3])
    lo = _rest_tolerance(s2, rest_tol, tiny)
    if w2 == 0.0:
        slowest = math.sqrt(v2)
    elif planar:
        wy = tw[2, i]
        cx, cz = tw[1, i] / wy, -tw[0, i] / wy
        dx = max(x0 - cx, cx - x1, zero)
        dz = max(z0 - cz, cz - z1, zero)
        slowest = abs(wy) * math.sqrt(dx * dx + dz * dz)
    else:
        vw = tw[0, i] * tw[3, i] + tw[1, i] * tw[4, i] + tw[2, i] * tw[5, i]
        slowest = abs(vw) / math.sqrt(w2)
    return lo, hi, slowest * (1 - 64 * eps) > hi + 16 * eps * scale


@_jit(inline=True)
def _exact_tolerances(planar, tw, nb, r, rest_tol):
    """The rest tolerance of each twist column of tw (width, nb): a pass over every pair."""
    tiny = np.finfo(tw.dtype).tiny
    s2max = np.zeros(nb, dtype=tw.dtype)
    for f in range(r.shape[0]):
        rx, ry, rz = r[f, 0], r[f, 1], r[f, 2]
        for i in range(nb):
            if planar:
                s2 = _planar_speed2(tw, i, rx, rz)[2]
            else:
                s2 = _spatial_speed2(tw, i, rx, ry, rz)[3]
            s2max[i] = max(s2max[i], s2)
    tol = np.empty(nb, dtype=tw.dtype)
    for i in range(nb):
        tol[i] = _rest_tolerance(s2max[i], rest_tol, tiny)
    return tol


@_jit(inline=True)
def _moving(s, lo, hi, band, zero):
    """(moving, band) for a facet of speed s: moving above hi; `band` keeps the largest speed
    at most hi (the block is ambiguous when that exceeds lo)."""
    moving = s > hi
    return moving, max(band, zero if moving else s)


@_jit(inline=True)
def _spatial_direction(vx, vy, vz, inv, nx, ny, nz, side, u, i):
    """u = v inv and x3 = n_d . u into column i of u (4, nb); returns n . u."""
    ux = vx * inv
    uy = vy * inv
    uz = vz * inv
    un = ux * nx + uy * ny + uz * nz
    u[0, i] = ux
    u[1, i] = uy
    u[2, i] = uz
    u[3, i] = side * un      # n_d . u, exactly: n_d is +-n
    return un


@_jit(inline=True)
def _planar_direction(vx, vz, inv, nx, nz, side, u, i):
    """(u_x, u_z) = v inv and x3 = n_d . u into column i of u (3, nb); returns n . u."""
    ux = vx * inv
    uz = vz * inv
    un = ux * nx + uz * nz
    u[0, i] = ux
    u[1, i] = uz
    u[2, i] = side * un
    return un


@_jit(inline=True)
def _spatial_pass(tw, nb, lo, hi, all_moving, r, n, nd, poly, w, mu, c, acc):
    """Wrenches / xi_n of the twist columns tw (6, nb) summed over every facet into acc
    (6, nb); True when a facet's speed lies between lo and hi (acc is then to be recomputed
    with the exact tolerance). all_moving: no facet rests for any twist (no rest test)."""
    zero, one, lead_tol = c[0], c[1], c[2]
    capped = mu < np.inf
    u = np.empty((4, nb), dtype=tw.dtype)      # ux, uy, uz, x3
    a = np.empty((3, nb), dtype=tw.dtype)
    kw = np.empty(nb, dtype=tw.dtype)
    band = np.zeros(nb, dtype=tw.dtype)
    for f in range(r.shape[0]):
        rx, ry, rz = r[f, 0], r[f, 1], r[f, 2]
        nx, ny, nz = n[f, 0], n[f, 1], n[f, 2]
        ndx, ndy, ndz = nd[f, 0], nd[f, 1], nd[f, 2]
        side = _side(nx, ny, nz, ndx, ndy, ndz, one)
        wf = w[f]
        if all_moving:
            for i in range(nb):
                vx, vy, vz, s2 = _spatial_speed2(tw, i, rx, ry, rz)
                inv = one / math.sqrt(s2)
                un = _spatial_direction(vx, vy, vz, inv, nx, ny, nz, side, u, i)
                kw[i] = wf if un >= -lead_tol else zero
        else:
            for i in range(nb):
                vx, vy, vz, s2 = _spatial_speed2(tw, i, rx, ry, rz)
                s = math.sqrt(s2)
                moving, band[i] = _moving(s, lo[i], hi[i], band[i], zero)
                inv = one / s if moving else zero
                un = _spatial_direction(vx, vy, vz, inv, nx, ny, nz, side, u, i)
                kw[i] = wf if (moving and un >= -lead_tol) else zero
        p = _coefficients(poly, f)
        # alpha before the cap: f1 n_d + f2 u - f3 z, one cubic per loop. Each loop then
        # holds its ten coefficients in registers; the three cubics in one loop (thirty, on
        # AVX2's sixteen registers) reloaded them at every step: 3-5 % slower. f2 u first and
        # then f1 n_d + (f2 u), the FMA the compiler formed from the one-loop sum: the
        # wrenches are the same bits as before (compared, planar and 6D, float64 and
        # float32, compiled for x86-64-v3 and for AVX-512).
        for i in range(nb):
            x3 = u[3, i]
            f2 = _cubic(p, 10, -u[2, i], x3, x3 * x3)
            a[0, i] = f2 * u[0, i]
            a[1, i] = f2 * u[1, i]
            a[2, i] = f2 * u[2, i]
        for i in range(nb):
            x3 = u[3, i]
            f1 = _cubic(p, 0, -u[2, i], x3, x3 * x3)
            a[0, i] = f1 * ndx + a[0, i]
            a[1, i] = f1 * ndy + a[1, i]
            a[2, i] = f1 * ndz + a[2, i]
        for i in range(nb):
            x3 = u[3, i]
            a[2, i] = a[2, i] - _cubic(p, 20, -u[2, i], x3, x3 * x3)
        for i in range(nb):
            ax, ay, az = a[0, i], a[1, i], a[2, i]
            if capped:
                ax, ay, az = _cap(ax, ay, az, nx, ny, nz, mu, one)
            k = kw[i]
            fx = k * ax
            fy = k * ay
            fz = k * az
            acc[0, i] += fx
            acc[1, i] += fy
            acc[2, i] += fz
            acc[3, i] += ry * fz - rz * fy
            acc[4, i] += rz * fx - rx * fz
            acc[5, i] += rx * fy - ry * fx
    for i in range(nb):
        if band[i] > lo[i]:
            return True
    return False


@_jit(inline=True)
def _planar_pass(tw, nb, lo, hi, all_moving, r, n, nd, poly, w, mu, c, acc):
    """`_spatial_pass` for planar twist columns tw (3, nb) = (vx, vz, wy): (Fx, Fz, My) / xi_n
    into acc (3, nb)."""
    zero, one, lead_tol = c[0], c[1], c[2]
    capped = mu < np.inf
    u = np.empty((3, nb), dtype=tw.dtype)      # ux, uz, x3
    a = np.empty((3, nb), dtype=tw.dtype)
    kw = np.empty(nb, dtype=tw.dtype)
    band = np.zeros(nb, dtype=tw.dtype)
    for f in range(r.shape[0]):
        rx, rz = r[f, 0], r[f, 2]
        nx, ny, nz = n[f, 0], n[f, 1], n[f, 2]
        ndx, ndy, ndz = nd[f, 0], nd[f, 1], nd[f, 2]
        side = _side(nx, ny, nz, ndx, ndy, ndz, one)
        wf = w[f]
        if all_moving:
            for i in range(nb):
                vx, vz, s2 = _planar_speed2(tw, i, rx, rz)
                inv = one / math.sqrt(s2)
                un = _planar_direction(vx, vz, inv, nx, nz, side, u, i)
                kw[i] = wf if un >= -lead_tol else zero
        else:
            for i in range(nb):
                vx, vz, s2 = _planar_speed2(tw, i, rx, rz)
                s = math.sqrt(s2)
                moving, band[i] = _moving(s, lo[i], hi[i], band[i], zero)
                inv = one / s if moving else zero
                un = _planar_direction(vx, vz, inv, nx, nz, side, u, i)
                kw[i] = wf if (moving and un >= -lead_tol) else zero
        p = _coefficients(poly, f)
        for i in range(nb):    # one cubic per loop, as in _spatial_pass
            x3 = u[2, i]
            f2 = _cubic(p, 10, -u[1, i], x3, x3 * x3)
            a[0, i] = f2 * u[0, i]
            a[2, i] = f2 * u[1, i]
        for i in range(nb):
            x3 = u[2, i]
            f1 = _cubic(p, 0, -u[1, i], x3, x3 * x3)
            a[0, i] = f1 * ndx + a[0, i]
            a[1, i] = f1 * ndy              # u.y = 0
            a[2, i] = f1 * ndz + a[2, i]
        for i in range(nb):
            x3 = u[2, i]
            a[2, i] = a[2, i] - _cubic(p, 20, -u[1, i], x3, x3 * x3)
        for i in range(nb):
            ax, ay, az = a[0, i], a[1, i], a[2, i]
            if capped:
                ax, ay, az = _cap(ax, ay, az, nx, ny, nz, mu, one)
            k = kw[i]
            fx = k * ax
            fz = k * az
            acc[0, i] += fx
            acc[1, i] += fz
            acc[2, i] += rz * fx - rx * fz
    for i in range(nb):
        if band[i] > lo[i]:
            return True
    return False
