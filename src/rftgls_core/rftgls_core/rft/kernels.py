"""Fused Agarwal 3D-RFT wrench kernels (numba): one pass over twists x facets, no temporaries.

Same arithmetic as `agarwal._PreparedAgarwal.stress` + `engine.BuriedBody` (the numpy path is
the reference; tests hold the two together to 1e-12). numpy needs ~130 array passes per
pair and is bound by memory traffic; the fused loop keeps a pair's numbers in registers and a
block's in L1 (the arithmetic: kernel_pairs.py).

Layout, chosen for the SIMD lanes: twists are processed in blocks of `BLOCK`, the facet loop
is outside and the twist loop inside. Each twist of a block owns its accumulators, so the
inner loops carry no reduction and LLVM vectorises them without reassociating any sum: every
twist's wrench is summed over facets in facet order, whatever the lanes, the block, its
neighbours in it or the thread count (results are bitwise independent of all of them). A
block's twists are first copied into an array of their own, padded to a multiple of `LANES`
(`_load`): read in place, the loop's speed depended on where the caller's arrays lay (2-3x
from one process to the next), and small counts ran scalar. Branches are selects (a trailing
or resting pair gets weight 0), `error_model='numpy'` keeps division free of Python's zero
check, and `fastmath` allows only contraction into FMA (a rounding difference of one ulp per
operation, far inside the 1e-12 agreement).

Order: in calls of more than one block, the twists for which no facet can be at rest
(kernel_pairs._twist_bounds; nearly all) are blocked together, the others after them, so that
most blocks run without the rest test. Results do not depend on the order (see above);
`_store` puts each back in its place.

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

from .kernel_pairs import (
    AVAILABLE,
    _exact_tolerances,
    _extent,
    _jit,
    _planar_pass,
    _spatial_pass,
    _twist_bounds,
    numba,
)

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


@_jit(inline=True)
def _load(tw, order, m0, m1):
    """Twists order[m0:m1] of tw (width, M) copied into a block of their own, (width, np) with
    np the count padded to a multiple of LANES by copies of the first; returns (block, np).

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
            loc[j, i] = tw[j, order[m0 + i]] if i < nb else tw[j, order[m0]]
    return loc, npad


@_jit(inline=True)
def _store(acc, order, m0, m1, out):
    """The block accumulators acc (width, >= m1 - m0) into the rows order[m0:m1] of out."""
    for i in range(m1 - m0):
        for j in range(acc.shape[0]):
            out[order[m0 + i], j] = acc[j, i]


@_jit()
def _order(planar, tw, r, c):
    """(order, n_moving, extent): the twist columns of tw, those for which every facet
    certainly moves first (n_moving of them), the others after; extent = _extent(r)."""
    m = tw.shape[1]
    ext = _extent(planar, r)
    moves = np.empty(m, dtype=np.bool_)
    for i in range(m):
        moves[i] = _twist_bounds(planar, tw, i, r, ext[0], ext[1], ext[2], ext[3], ext[4],
                                 c[3], c[4])[2]
    order = np.empty(m, dtype=np.int64)
    if m <= BLOCK:
        # one block either way: a second one for a few twists would cost a pass over the
        # facets more than the rest test it saves (24 twists: 23 -> 31 us)
        for i in range(m):
            order[i] = i
        return order, m if moves.all() else 0, ext
    k = 0
    for i in range(m):
        if moves[i]:
            order[k] = i
            k += 1
    n_moving = k
    for i in range(m):
        if not moves[i]:
            order[k] = i
            k += 1
    return order, n_moving, ext


@_jit(inline=True)
def _block_range(b, n_moving, m):
    """Positions [m0, m1) in the order of block b: blocks never mix the two kinds of twist."""
    nbm = (n_moving + BLOCK - 1) // BLOCK
    if b < nbm:
        return b * BLOCK, min(n_moving, (b + 1) * BLOCK)
    m0 = n_moving + (b - nbm) * BLOCK
    return m0, min(m, m0 + BLOCK)


@_jit(inline=True)
def _n_blocks(n_moving, m):
    return (n_moving + BLOCK - 1) // BLOCK + (m - n_moving + BLOCK - 1) // BLOCK


@_jit()
def _block(planar, tw, order, m0, m1, ext, r, n, nd, poly, w, mu, c, out):
    """The twists order[m0:m1] of tw (planar: (3, M) -> out (M, 3); else (6, M) -> (M, 6))."""
    loc, nb = _load(tw, order, m0, m1)
    lo = np.empty(nb, dtype=loc.dtype)
    hi = np.empty(nb, dtype=loc.dtype)
    moving = True
    for i in range(nb):
        lo[i], hi[i], moves = _twist_bounds(planar, loc, i, r, ext[0], ext[1], ext[2], ext[3],
                                            ext[4], c[3], c[4])
        moving = moving and moves
    acc = np.zeros((3 if planar else 6, nb))
    for exact in (False, True):
        if exact:
            # a facet between lo and hi: once more with the exact tolerance
            acc[:] = 0.0
            lo = hi = _exact_tolerances(planar, loc, nb, r, c[3])
            moving = False
        if planar:
            ambiguous = _planar_pass(loc, nb, lo, hi, moving, r, n, nd, poly, w, mu, c, acc)
        else:
            ambiguous = _spatial_pass(loc, nb, lo, hi, moving, r, n, nd, poly, w, mu, c, acc)
        if not ambiguous:
            break
    _store(acc, order, m0, m1, out)


@_jit()
def blocks_serial(planar, tw, r, n, nd, poly, w, mu, c, out):
    """All blocks of tw in one thread (planar: bool, see `_block`)."""
    if r.shape[0] == 0:
        return
    order, n_moving, ext = _order(planar, tw, r, c)
    for b in range(_n_blocks(n_moving, tw.shape[1])):
        m0, m1 = _block_range(b, n_moving, tw.shape[1])
        _block(planar, tw, order, m0, m1, ext, r, n, nd, poly, w, mu, c, out)


@_jit(parallel=True)
def blocks_parallel(planar, tw, r, n, nd, poly, w, mu, c, out):
    """As blocks_serial, the blocks spread over numba's threads."""
    if r.shape[0] == 0:
        return
    order, n_moving, ext = _order(planar, tw, r, c)
    for b in _prange(_n_blocks(n_moving, tw.shape[1])):
        m0, m1 = _block_range(b, n_moving, tw.shape[1])
        _block(planar, tw, order, m0, m1, ext, r, n, nd, poly, w, mu, c, out)


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
