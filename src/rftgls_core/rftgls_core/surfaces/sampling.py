"""Unit twists spread uniformly on the sphere of the scaled twist metric.

A Fibonacci sphere: no duplicates, no pole clusters, no lat-long degeneracies (which make
Qhull slow and alpha spectra collapse, docs/design/limit-surfaces.md).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .scaling import Scaling

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


@dataclass(frozen=True)
class TwistSample:
    """Sampled twists: `scaled` unit vectors (n, 3) and the raw directions (n, 3) for wrench_fn."""

    scaled: np.ndarray
    raw: np.ndarray

    def __len__(self) -> int:
        return len(self.scaled)


def sample_twists(scaling: Scaling, n: int) -> TwistSample:
    """n twists uniform in the scaled metric, converted to raw (vx, vz, wy) unit directions."""
    ts = fibonacci_sphere(n)
    return TwistSample(scaled=ts, raw=scaling.twist_from_scaled(ts))
