"""Unit twists spread uniformly on the sphere of the scaled twist metric (a leaf: numpy only).

Convert them to raw (vx, vz, wy) directions with `Scaling.twist_from_scaled`.

A Fibonacci sphere: no duplicates, no pole clusters, no lat-long degeneracies (which make
Qhull slow and alpha spectra collapse, docs/design/limit-surfaces.md).
"""
from __future__ import annotations

import numpy as np

_GOLDEN_ANGLE = np.pi * (3.0 - np.sqrt(5.0))


def fibonacci_sphere(n: int) -> np.ndarray:
    """n unit vectors (n, 3), area-uniform; z_i = 1 - (2 i + 1)/n, longitudes by the golden angle.

    Deterministic, so a sphere triangulation built once is valid for every later call with the
    same n.
    """
    n = int(n)
    if n < 4:
        raise ValueError(f'need at least 4 twists on the sphere, got {n}')
    i = np.arange(n, dtype=float)
    z = 1.0 - (2.0 * i + 1.0) / n
    r = np.sqrt(np.clip(1.0 - z * z, 0.0, None))
    lon = _GOLDEN_ANGLE * i
    return np.column_stack([r * np.cos(lon), r * np.sin(lon), z])
