"""Multilinear interpolation on a regular (non-uniform) grid: cell location and corner weights.

Pure functions, two flavours of the same arithmetic:
- single query, pure Python lists + bisect (numpy's per-call overhead, ~1 us per ufunc on a
  scalar, would dominate a 16-32 corner blend; see docs/design/limit-surfaces.md);
- batch query, vectorised numpy over N points (one searchsorted per axis).

Out-of-range coordinates are clamped to the end node; `side` says which way (-1 below,
+1 above, 0 inside) so the caller can refuse the query (CapacityMap answers OUT_OF_RANGE with
no value). Neither clamped nor linearly extrapolated values are ever returned as answers.

Corners whose weight is exactly zero are dropped (a query on a node or a face uses only the
nodes it lies on), so an unusable neighbour with zero weight does not poison the answer.
"""
from __future__ import annotations

from bisect import bisect_right
from collections.abc import Sequence

import numpy as np

# Coordinates within this fraction of a cell of a node ARE on the node, so a measured leg
# angle of -40.00004 deg (the serial link carries micro-radians) or -40.00000000000001 deg
# (degrees -> radians) does not pull in the next node with a weight of 1e-6. 1e-5 of a 20 deg
# cell is 0.0002 deg, of a 5 mm cell 0.05 um: far below any sensor.
SNAP = 1e-5


def locate(xs: Sequence[float], x: float) -> tuple[int, float, int]:
    """Cell of x on the increasing axis xs (len >= 2): (lower node i, fraction t, side).

    t in [0, 1) is the weight of node i + 1 (1 - t that of node i). Clamped coordinates land
    ON the end node with t == 0.0: below the axis (0, 0.0, -1), above it (n - 1, 0.0, +1).
    A coordinate exactly on a node also gives t == 0.0 at that node, so the neighbouring
    node gets weight exactly 0 and is never read (callers skip zero weights BEFORE indexing,
    which also keeps index i + 1 == n from being touched).
    """
    n = len(xs)
    tol = SNAP * (xs[1] - xs[0])
    if x <= xs[0]:
        return 0, 0.0, (-1 if x < xs[0] - tol else 0)
    if x >= xs[n - 1]:
        return n - 1, 0.0, (1 if x > xs[n - 1] + tol else 0)
    i = bisect_right(xs, x) - 1
    x0 = xs[i]
    t = (x - x0) / (xs[i + 1] - x0)
    if t < SNAP:
        return i, 0.0, 0
    if t > 1.0 - SNAP:
        return i + 1, 0.0, 0
    return i, t, 0


def weights4(t0: float, t1: float, t2: float, t3: float) -> list[float]:
    """The 16 corner weights of a 4-D cell, corner c = bits (b0 b1 b2 b3), b0 most significant.

    Ordered like `corner_offsets(strides)`; they sum to 1 and are exactly 0 for the far
    corners of every axis with t == 0.
    """
    u2, u3 = 1.0 - t2, 1.0 - t3
    w01 = ((1.0 - t0) * (1.0 - t1), (1.0 - t0) * t1, t0 * (1.0 - t1), t0 * t1)
    w012 = [w * s for w in w01 for s in (u2, t2)]
    return [w * s for w in w012 for s in (u3, t3)]


def locate_many(axis: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Vectorised `locate`: (i intp, t float64, side int8) for every x (same shape as x)."""
    axis = np.asarray(axis, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    n = len(axis)
    xc = np.clip(x, axis[0], axis[-1])
    i = np.clip(np.searchsorted(axis, xc, side='right') - 1, 0, n - 2)
    t = (xc - axis[i]) / (axis[i + 1] - axis[i])
    t = np.where(t < SNAP, 0.0, np.where(t > 1.0 - SNAP, 1.0, t))
    tol = SNAP * (axis[1] - axis[0])
    side = np.where(x < axis[0] - tol, -1, np.where(x > axis[-1] + tol, 1, 0)).astype(np.int8)
    return i, t, side


def corner_offsets(strides: Sequence[int]) -> tuple[np.ndarray, np.ndarray]:
    """All 2**d corners of a cell: flat offsets (2**d,) and bit patterns (2**d, d) in {0, 1}."""
    d = len(strides)
    bits = ((np.arange(2 ** d)[:, None] >> np.arange(d)[::-1]) & 1).astype(np.intp)
    return bits @ np.asarray(strides, dtype=np.intp), bits


def flat_strides(shape: Sequence[int]) -> tuple[int, ...]:
    """C-order strides (in elements) of an array of `shape`."""
    strides, acc = [], 1
    for n in reversed(shape):
        strides.append(acc)
        acc *= int(n)
    return tuple(reversed(strides))
