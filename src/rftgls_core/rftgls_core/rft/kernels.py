"""Fused Agarwal 3D-RFT wrench kernels (numba): one pass over twists x facets, no temporaries.

Same arithmetic as `agarwal._PreparedAgarwal.stress` + `engine.BuriedBody` (the numpy path is
the reference; tests hold the two together to 1e-12). numpy needs ~130 array passes per
pair and is bound by memory traffic; the fused loop keeps everything in registers.

Layout, chosen for the SIMD lanes: twists are processed in blocks of `BLOCK`, the facet loop
is outside and the twist loop inside. Each twist of a block owns its accumulators, so the
inner loop carries no reduction and LLVM vectorises it without reassociating any sum: every
twist's wrench is summed over facets in facet order, whatever the lanes, the block size or
the thread count (results are bitwise independent of the number of threads). A block's
twists are first copied into an array of its own, padded to a multiple of `LANES` (`_load`):
read in place, the loop's speed depended on where the caller's arrays lay (2-3x from one
process to the next), and small counts ran scalar. Branches are
selects (a trailing or resting pair gets weight 0), `error_model='numpy'` keeps division free
of Python's zero check, and `fastmath` allows only contraction into FMA (a rounding
difference of one ulp per operation, far inside the 1e-12 agreement).

Cores: `*_parallel` runs the blocks in a numba `prange` (the thread count is
`numba.set_num_threads`); `*_serial` runs the same blocks in one thread. The engine picks.

Precision: the kernels are generic over float64 and float32 facet/twist arrays (the constants
come in as arguments of the same dtype so nothing silently widens); accumulators are float64.
If numba is missing, `AVAILABLE` is False and the engine uses numpy.
"""
from __future__ import annotations

import functools
import math
import multiprocessing
import os
import threading

import numpy as np

# OpenMP threads that spin after a parallel call steal the core from the thread doing the next
# serial step, and on a shared or busy machine make two threads slower than one (measured:
# 258 ms on two threads against 139 ms on one, load 16; 136 ms on two with passive waits).
# Sleeping threads cost a wake-up per call, small next to calls worth threading. Read by
# libgomp when numba first starts its pool; a value set by the user wins.
os.environ.setdefault('OMP_WAIT_POLICY', 'PASSIVE')

try:
    import numba
    AVAILABLE = True
except ImportError:  # pragma: no cover - exercised only on machines without numba
    numba = None  # type: ignore[assignment]
    AVAILABLE = False
_prange = numba.prange if AVAILABLE else range

LEADING_TOL = 1e-12
# A facet is at rest when its speed is <= REST_TOL times the fastest facet's speed.
REST_TOL = 1e-12
# The upper bound of the fastest facet's speed, |v| + |w| max|r|, is widened by this factor so
# that rounding (a few ulp; float32's 6e-8 included) cannot put it below the computed speeds.
REST_MARGIN = 1.001
# Twists per block: a multiple of the widest SIMD width (8 float64 / 16 float32 lanes on
# AVX-512); the block's accumulators (6 x BLOCK) stay in L1.
BLOCK = 64
# A block's twist count is padded to a multiple of this (copies of its first twist, results
# dropped): the vectorised twist loop then has no scalar remainder, which for the few-twist
# calls of a warm step (3-60 twists) was most of the loop (15 twists: 31 -> 10 us).
LANES = 8
# Below this many facet-twist pairs a thread start costs more than it saves.
PARALLEL_MIN_PAIRS = 50_000
_FASTMATH = {'contract'}

# Floating-point operations per facet-twist pair, counted in the code below as a person would
# count them (a multiply-add is two, a square root or a division one; sign flips, compares,
# selects and max none), for `rftgls bench`'s share of the machine's peak:
#
#   step                                     spatial  planar
#   velocity at the facet (v + w x r)             12       4
#   squared speed, speed, its inverse            5+2     3+2
#   unit direction u                               3       2
#   n . u, and x3 = n_d . u = +-(n . u)          5+1     3+1
#   x3^2 and the three cubics (9 FMA each)      1+54    1+54
#   alpha before the cap: f1 n_d + f2 u - f3 z    10       8
#   friction cap (two dot products, |t|, the
#     ratio, the capped stress)                   28      28
#   weight, force and moment sums                 18       8
#   total                                        139     114
#
# Each block of twists also spends ~5 flops per facet on its rest-tolerance bounds (not
# counted: 1/BLOCK of a pair).
FLOPS_PER_PAIR = {'spatial': 139, 'planar': 114}


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
def _rest_tolerance(s2max, rest_tol, tiny):
    """A facet is at rest below rest_tol x the fastest facet's speed (s2max: its square; the
    tolerance floored at the dtype's tiny). sqrt is monotone and correctly rounded, so this is
    rest_tol x the largest computed speed."""
    return rest_tol * max(math.sqrt(s2max), tiny)


@_jit(inline=True)
def _store(acc, m0, nb, out):
    """The first nb columns of the block accumulators acc (width, >= nb) into
    out[m0:m0 + nb, :width] (twist-major)."""
    for i in range(nb):
        for j in range(acc.shape[0]):
            out[m0 + i, j] = acc[j, i]


@_jit(inline=True)
def _load(tw, m0, m1):
    """Twists m0..m1 of tw (width, M) copied into a block of their own, (width, np) with np
    the count padded to a multiple of LANES by copies of the first twist; returns (block, np).

    The copy is what lets the twist loop run on the SIMD lanes at every call: reading tw in
    place, the loop's speed depended on where the caller's arrays happened to lie relative to
    the accumulators (the same 60-twist call took 60 or 200 us from one process to the next,
    bitwise the same results), and a count below the vector loop's width ran all scalar.
    """
    nb = m1 - m0
    npad = min(BLOCK, (nb + LANES - 1) // LANES * LANES)
    loc = np.empty((tw.shape[0], npad), dtype=tw.dtype)
    for j in range(tw.shape[0]):
        for i in range(npad):
            loc[j, i] = tw[j, m0 + i] if i < nb else tw[j, m0]
    return loc, npad


@_jit(inline=True)
def _side(nx, ny, nz, ndx, ndy, ndz, one):
    """+1 when n_d is n, -1 when it is -n (agarwal.downward_normal gives one or the other)."""
    return one if (ndx == nx and ndy == ny and ndz == nz) else -one


@_jit(inline=True)
def _spatial_speed2(tw, i, rx, ry, rz):
    """Squared speed of twist i of tw (6, nb) at the point r."""
    vx = tw[0, i] + tw[4, i] * rz - tw[5, i] * ry
    vy = tw[1, i] + tw[5, i] * rx - tw[3, i] * rz
    vz = tw[2, i] + tw[3, i] * ry - tw[4, i] * rx
    return vx, vy, vz, vx * vx + vy * vy + vz * vz


@_jit(inline=True)
def _planar_speed2(tw, i, rx, rz):
    """In-plane velocity and squared speed of planar twist i of tw (3, nb) at (rx, rz)."""
    vx = tw[0, i] + tw[2, i] * rz
    vz = tw[1, i] - tw[2, i] * rx
    return vx, vz, vx * vx + vz * vz


@_jit(inline=True)
def _rest_bounds(planar, tw, nb, r, rest_tol, margin, exact):
    """Per twist of a block, (lo, hi) with lo <= the rest tolerance <= hi.

    The exact tolerance needs every facet's speed first, a pass over all pairs that cost a
    sixth of the kernel. The bounds cost a pass over the facets: hi from |v| + |w| max|r|
    (times `margin` for rounding), lo from the exact formula on four of the facets. A facet
    below lo rests and one above hi moves, as with the exact tolerance; one in between sends
    its block through `exact` (lo = hi = the tolerance), which on real bodies never happens:
    it takes a facet within 1e-12 of the fastest one's speed of resting.
    """
    tiny = np.finfo(tw.dtype).tiny
    nf = r.shape[0]
    lo = np.empty(nb, dtype=tw.dtype)
    hi = np.empty(nb, dtype=tw.dtype)
    if exact or nf == 0:
        s2max = np.zeros(nb, dtype=tw.dtype)
        for f in range(nf):
            rx, ry, rz = r[f, 0], r[f, 1], r[f, 2]
            for i in range(nb):
                if planar:
                    s2 = _planar_speed2(tw, i, rx, rz)[2]
                else:
                    s2 = _spatial_speed2(tw, i, rx, ry, rz)[3]
                s2max[i] = max(s2max[i], s2)
        for i in range(nb):
            lo[i] = hi[i] = _rest_tolerance(s2max[i], rest_tol, tiny)
        return lo, hi
    rmax2 = tw.dtype.type(0)
    for f in range(nf):
        rx, ry, rz = r[f, 0], r[f, 1], r[f, 2]
        rmax2 = max(rmax2, rx * rx + rz * rz if planar else rx * rx + ry * ry + rz * rz)
    rmax = math.sqrt(rmax2)
    for i in range(nb):
        if planar:
            v2 = tw[0, i] * tw[0, i] + tw[1, i] * tw[1, i]
            w2 = tw[2, i] * tw[2, i]
        else:
            v2 = tw[0, i] * tw[0, i] + tw[1, i] * tw[1, i] + tw[2, i] * tw[2, i]
            w2 = tw[3, i] * tw[3, i] + tw[4, i] * tw[4, i] + tw[5, i] * tw[5, i]
        hi[i] = rest_tol * max(margin * (math.sqrt(v2) + math.sqrt(w2) * rmax), tiny)
        s2 = tw.dtype.type(0)
        for f in (0, nf // 3, (2 * nf) // 3, nf - 1):
            if planar:
                s2 = max(s2, _planar_speed2(tw, i, r[f, 0], r[f, 2])[2])
            else:
                s2 = max(s2, _spatial_speed2(tw, i, r[f, 0], r[f, 1], r[f, 2])[3])
        lo[i] = _rest_tolerance(s2, rest_tol, tiny)
    return lo, hi


@_jit(inline=True)
def _moving(s, lo, hi, band, zero):
    """(moving, band) for a facet of speed s: moving above hi; `band` keeps the largest speed
    at most hi (the block is ambiguous when that exceeds lo, see `_rest_bounds`)."""
    moving = s > hi
    return moving, max(band, zero if moving else s)


@_jit()
def _spatial_block(tw, m0, m1, r, n, nd, poly, w, mu, c, out):
    """Wrenches of twists m0..m1 (tw (6, M), SoA) into out[m0:m1]; c = (0, 1, lead, rest,
    margin); see `_spatial_pass`."""
    tw, nb = _load(tw, m0, m1)
    acc = np.zeros((6, nb))
    lo, hi = _rest_bounds(False, tw, nb, r, c[3], c[4], False)
    if _spatial_pass(tw, nb, lo, hi, r, n, nd, poly, w, mu, c, acc):
        acc[:] = 0.0
        lo, hi = _rest_bounds(False, tw, nb, r, c[3], c[4], True)
        _spatial_pass(tw, nb, lo, hi, r, n, nd, poly, w, mu, c, acc)
    _store(acc, m0, m1 - m0, out)


@_jit(inline=True)
def _spatial_pass(tw, nb, lo, hi, r, n, nd, poly, w, mu, c, acc):
    """Sums of the block's twists tw (6, nb) into acc (6, nb); True when a facet's speed lies
    between lo and hi (see `_rest_bounds`; acc is then to be recomputed).

    Per facet the twist loop runs as three short loops through small arrays in L1: direction,
    weight and x3; stress; cap and sums. In one long loop body the dependency chain (two
    square roots, two divisions, the cubics) was ~200 cycles, more than the CPU's reorder
    window overlaps from one iteration to the next; short bodies it overlaps.
    """
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
        for i in range(nb):
            vx, vy, vz, s2 = _spatial_speed2(tw, i, rx, ry, rz)
            s = math.sqrt(s2)
            moving, band[i] = _moving(s, lo[i], hi[i], band[i], zero)
            inv = one / s if moving else zero
            ux = vx * inv
            uy = vy * inv
            uz = vz * inv
            un = ux * nx + uy * ny + uz * nz
            kw[i] = wf if (moving and un >= -lead_tol) else zero
            u[0, i] = ux
            u[1, i] = uy
            u[2, i] = uz
            u[3, i] = side * un      # n_d . u, exactly: n_d is +-n
        p = _coefficients(poly, f)
        for i in range(nb):
            # alpha before the cap: f1 n_d + f2 u - f3 z
            f1, f2, f3 = _cubics(u[3, i], u[2, i], p)
            a[0, i] = f1 * ndx + f2 * u[0, i]
            a[1, i] = f1 * ndy + f2 * u[1, i]
            a[2, i] = f1 * ndz + f2 * u[2, i] - f3
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


@_jit()
def _planar_block(tw, m0, m1, r, n, nd, poly, w, mu, c, out):
    """Planar (Fx, Fz, My) of twists m0..m1 (tw (3, M) = vx, vz, wy) into out[m0:m1]."""
    tw, nb = _load(tw, m0, m1)
    acc = np.zeros((3, nb))
    lo, hi = _rest_bounds(True, tw, nb, r, c[3], c[4], False)
    if _planar_pass(tw, nb, lo, hi, r, n, nd, poly, w, mu, c, acc):
        acc[:] = 0.0
        lo, hi = _rest_bounds(True, tw, nb, r, c[3], c[4], True)
        _planar_pass(tw, nb, lo, hi, r, n, nd, poly, w, mu, c, acc)
    _store(acc, m0, m1 - m0, out)


@_jit(inline=True)
def _planar_pass(tw, nb, lo, hi, r, n, nd, poly, w, mu, c, acc):
    """`_spatial_pass` for planar twists tw (3, nb) = (vx, vz, wy): (Fx, Fz, My) into acc."""
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
        for i in range(nb):
            vx, vz, s2 = _planar_speed2(tw, i, rx, rz)
            s = math.sqrt(s2)
            moving, band[i] = _moving(s, lo[i], hi[i], band[i], zero)
            inv = one / s if moving else zero
            ux = vx * inv
            uz = vz * inv
            un = ux * nx + uz * nz
            kw[i] = wf if (moving and un >= -lead_tol) else zero
            u[0, i] = ux
            u[1, i] = uz
            u[2, i] = side * un
        p = _coefficients(poly, f)
        for i in range(nb):
            f1, f2, f3 = _cubics(u[2, i], u[1, i], p)
            a[0, i] = f1 * ndx + f2 * u[0, i]
            a[1, i] = f1 * ndy              # u.y = 0
            a[2, i] = f1 * ndz + f2 * u[1, i] - f3
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


@_jit(inline=True)
def _block(planar, b, tw, r, n, nd, poly, w, mu, c, out):
    """Block number b of twists tw (planar: (3, M) -> out (M, 3); else (6, M) -> (M, 6))."""
    m0, m1 = b * BLOCK, min(tw.shape[1], (b + 1) * BLOCK)
    if planar:
        _planar_block(tw, m0, m1, r, n, nd, poly, w, mu, c, out)
    else:
        _spatial_block(tw, m0, m1, r, n, nd, poly, w, mu, c, out)


@_jit()
def blocks_serial(planar, tw, r, n, nd, poly, w, mu, c, out):
    """All blocks of tw in one thread (planar: bool, see `_block`)."""
    for b in range((tw.shape[1] + BLOCK - 1) // BLOCK):
        _block(planar, b, tw, r, n, nd, poly, w, mu, c, out)


@_jit(parallel=True)
def blocks_parallel(planar, tw, r, n, nd, poly, w, mu, c, out):
    """As blocks_serial, the blocks spread over numba's threads."""
    for b in _prange((tw.shape[1] + BLOCK - 1) // BLOCK):
        _block(planar, b, tw, r, n, nd, poly, w, mu, c, out)


@_jit()
def twist_fault(t):
    """0 when every row of t (M, width) is finite and nonzero, 1 when some entry is NaN or inf,
    2 when some row is all zero (engine._check_twists in one pass: its numpy form cost about
    6 us per call, a third of a few-twist wrench call)."""
    zero = False
    for i in range(t.shape[0]):
        nonzero = False
        for j in range(t.shape[1]):
            x = t[i, j]
            if not math.isfinite(x):
                return 1
            if x != 0.0:
                nonzero = True
        if not nonzero:
            zero = True
    return 2 if zero else 0


# The engine's four entry points, args (tw, r, n, nd, poly, w, mu, c, out):
# (Fx, Fy, Fz, Mx, My, Mz) / xi_n per spatial twist, tw (6, M), and
# (Fx, Fz, My) / xi_n per planar twist, tw (3, M) = (vx, vz, wy); one thread or numba's threads.
spatial_serial = functools.partial(blocks_serial, False)
spatial_parallel = functools.partial(blocks_parallel, False)
planar_serial = functools.partial(blocks_serial, True)
planar_parallel = functools.partial(blocks_parallel, True)


def constants(dtype) -> np.ndarray:
    """(0, 1, LEADING_TOL, REST_TOL, REST_MARGIN) in the kernels' working dtype."""
    return np.array([0.0, 1.0, LEADING_TOL, REST_TOL, REST_MARGIN], dtype=dtype)


def threads() -> int:
    """Threads the parallel kernels use from this thread (1 without numba)."""
    return numba.get_num_threads() if AVAILABLE else 1


def max_threads() -> int:
    """Threads numba started with (NUMBA_NUM_THREADS, by default the CPU count); 1 without."""
    return int(getattr(numba.config, 'NUMBA_NUM_THREADS', 1)) if AVAILABLE else 1


def set_threads(n: int) -> None:
    """Threads for the parallel kernels, 1..numba.config.NUMBA_NUM_THREADS (calling thread)."""
    if not AVAILABLE:
        raise RuntimeError('numba is not installed')
    numba.set_num_threads(int(n))


def run_parallel(kernel, *args) -> None:
    """Call a *_parallel kernel with blocks handed out one at a time (dynamic schedule).

    A static split waits for the slowest thread; on a shared machine a descheduled thread
    would hold the whole call, while one-block chunks let the other thread take over.
    """
    prev = numba.get_parallel_chunksize()
    numba.set_parallel_chunksize(1)
    try:
        kernel(*args)
    finally:
        numba.set_parallel_chunksize(prev)


def use_parallel(pairs: int) -> bool:
    """Parallel kernels only for big calls, from the main thread of the main process.

    A pool worker is already one of N parallel workers (threads in each would oversubscribe
    the cores), and numba's fallback threading layer may not be entered from two Python
    threads at once; everywhere else the serial kernel gives the same numbers.
    """
    return (pairs >= PARALLEL_MIN_PAIRS and threads() > 1
            and threading.current_thread() is threading.main_thread()
            and multiprocessing.parent_process() is None)
