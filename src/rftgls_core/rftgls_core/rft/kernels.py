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
def _stress(ux, uy, uz, nx, ny, nz, ndx, ndy, ndz, p, capped, mu, one):
    """alpha / xi_n of one facet (n, n_d, ten-per-f_j cubic coefficients p) for unit u."""
    x1 = -uz
    x3 = ndx * ux + ndy * uy + ndz * uz
    x1s = x1 * x1
    x3s = x3 * x3
    # Monomial order of agarwal._MONOMIALS: (a, c) for a in 0..3, c in 0..3-a.
    m5 = x1 * x3
    m6 = x1 * x3s
    m8 = x1s * x3
    m3 = x3s * x3
    m9 = x1s * x1
    f1 = (p[0] + p[1] * x3 + p[2] * x3s + p[3] * m3 + p[4] * x1 + p[5] * m5 + p[6] * m6
          + p[7] * x1s + p[8] * m8 + p[9] * m9)
    f2 = (p[10] + p[11] * x3 + p[12] * x3s + p[13] * m3 + p[14] * x1 + p[15] * m5
          + p[16] * m6 + p[17] * x1s + p[18] * m8 + p[19] * m9)
    f3 = (p[20] + p[21] * x3 + p[22] * x3s + p[23] * m3 + p[24] * x1 + p[25] * m5
          + p[26] * m6 + p[27] * x1s + p[28] * m8 + p[29] * m9)
    ax = f1 * ndx + f2 * ux
    ay = f1 * ndy + f2 * uy
    az = f1 * ndz + f2 * uz - f3
    if capped:
        an = ax * nx + ay * ny + az * nz
        tx = ax - an * nx
        ty = ay - an * ny
        tz = az - an * nz
        tn = math.sqrt(tx * tx + ty * ty + tz * tz)
        lim = mu * abs(an)
        s = lim / tn if tn > lim else one
        ax = an * nx + s * tx
        ay = an * ny + s * ty
        az = an * nz + s * tz
    return ax, ay, az


@_jit(inline=True)
def _coefficients(poly, f):
    """Row f of poly (F, 30) as a tuple: scalars the compiler keeps in registers across the
    twist loop (an array row would be reloaded there for fear of aliasing the accumulators)."""
    q = poly[f]
    return (q[0], q[1], q[2], q[3], q[4], q[5], q[6], q[7], q[8], q[9], q[10], q[11], q[12], q[13],
            q[14], q[15], q[16], q[17], q[18], q[19], q[20], q[21], q[22], q[23], q[24], q[25],
            q[26], q[27], q[28], q[29])


@_jit(inline=True)
def _rest_tolerances(s2max, rest_tol):
    """Per twist of a block: a facet is at rest below rest_tol x the fastest facet speed
    (s2max: squared speeds, the tolerance floored at the dtype's tiny); in s2max's dtype."""
    nb = s2max.shape[0]
    tol = np.empty(nb, dtype=s2max.dtype)
    tiny = np.finfo(s2max.dtype).tiny
    # sqrt is monotone and correctly rounded: sqrt(max s^2) == max(sqrt(s^2)).
    for i in range(nb):
        tol[i] = rest_tol * max(math.sqrt(s2max[i]), tiny)
    return tol


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


@_jit()
def _spatial_block(tw, m0, m1, r, n, nd, poly, w, mu, c, out):
    """Wrenches of twists m0..m1 (tw (6, M), SoA) into out[m0:m1]; c = (0, 1, lead, rest)."""
    nout = m1 - m0
    tw, nb = _load(tw, m0, m1)
    nf = r.shape[0]
    zero, one, lead_tol, rest_tol = c[0], c[1], c[2], c[3]
    capped = mu < np.inf
    s2max = np.zeros(nb, dtype=tw.dtype)
    for f in range(nf):
        rx, ry, rz = r[f, 0], r[f, 1], r[f, 2]
        for i in range(nb):
            m = i
            vx = tw[0, m] + tw[4, m] * rz - tw[5, m] * ry
            vy = tw[1, m] + tw[5, m] * rx - tw[3, m] * rz
            vz = tw[2, m] + tw[3, m] * ry - tw[4, m] * rx
            s2max[i] = max(s2max[i], vx * vx + vy * vy + vz * vz)
    tol = _rest_tolerances(s2max, rest_tol)
    acc = np.zeros((6, nb))
    for f in range(nf):
        rx, ry, rz = r[f, 0], r[f, 1], r[f, 2]
        nx, ny, nz = n[f, 0], n[f, 1], n[f, 2]
        ndx, ndy, ndz = nd[f, 0], nd[f, 1], nd[f, 2]
        wf = w[f]
        p = _coefficients(poly, f)
        for i in range(nb):
            m = i
            vx = tw[0, m] + tw[4, m] * rz - tw[5, m] * ry
            vy = tw[1, m] + tw[5, m] * rx - tw[3, m] * rz
            vz = tw[2, m] + tw[3, m] * ry - tw[4, m] * rx
            s = math.sqrt(vx * vx + vy * vy + vz * vz)
            moving = s > tol[i]
            inv = one / s if moving else zero
            ux = vx * inv
            uy = vy * inv
            uz = vz * inv
            lead = moving and (ux * nx + uy * ny + uz * nz >= -lead_tol)
            ax, ay, az = _stress(ux, uy, uz, nx, ny, nz, ndx, ndy, ndz, p, capped, mu, one)
            k = wf if lead else zero
            fx = k * ax
            fy = k * ay
            fz = k * az
            acc[0, i] += fx
            acc[1, i] += fy
            acc[2, i] += fz
            acc[3, i] += ry * fz - rz * fy
            acc[4, i] += rz * fx - rx * fz
            acc[5, i] += rx * fy - ry * fx
    _store(acc, m0, nout, out)


@_jit()
def _planar_block(tw, m0, m1, r, n, nd, poly, w, mu, c, out):
    """Planar (Fx, Fz, My) of twists m0..m1 (tw (3, M) = vx, vz, wy) into out[m0:m1]."""
    nout = m1 - m0
    tw, nb = _load(tw, m0, m1)
    nf = r.shape[0]
    zero, one, lead_tol, rest_tol = c[0], c[1], c[2], c[3]
    capped = mu < np.inf
    s2max = np.zeros(nb, dtype=tw.dtype)
    for f in range(nf):
        rx, rz = r[f, 0], r[f, 2]
        for i in range(nb):
            m = i
            vx = tw[0, m] + tw[2, m] * rz
            vz = tw[1, m] - tw[2, m] * rx
            s2max[i] = max(s2max[i], vx * vx + vz * vz)
    tol = _rest_tolerances(s2max, rest_tol)
    acc = np.zeros((3, nb))
    for f in range(nf):
        rx, rz = r[f, 0], r[f, 2]
        nx, ny, nz = n[f, 0], n[f, 1], n[f, 2]
        ndx, ndy, ndz = nd[f, 0], nd[f, 1], nd[f, 2]
        wf = w[f]
        p = _coefficients(poly, f)
        for i in range(nb):
            m = i
            vx = tw[0, m] + tw[2, m] * rz
            vz = tw[1, m] - tw[2, m] * rx
            s = math.sqrt(vx * vx + vz * vz)
            moving = s > tol[i]
            inv = one / s if moving else zero
            ux = vx * inv
            uz = vz * inv
            lead = moving and (ux * nx + uz * nz >= -lead_tol)
            ax, ay, az = _stress(ux, zero, uz, nx, ny, nz, ndx, ndy, ndz, p, capped, mu, one)
            k = wf if lead else zero
            fx = k * ax
            fz = k * az
            acc[0, i] += fx
            acc[1, i] += fz
            acc[2, i] += rz * fx - rx * fz
    _store(acc, m0, nout, out)


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
    """(0, 1, LEADING_TOL, REST_TOL) in the kernels' working dtype."""
    return np.array([0.0, 1.0, LEADING_TOL, REST_TOL], dtype=dtype)


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
