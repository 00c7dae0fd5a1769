"""Capacity with an uncertainty band: medium-parameter covariance and state noise -> capacity.

Inputs (SI): the calibrated (xi_n, mu_surf) with their 2x2 covariance (calibrate.py writes it
into the medium JSON), and 1-sigma noise of the state estimate (h, thetaB). Two propagations:
  - 'linear': central differences with a step of one sigma per input (so mild curvature over
    the band is averaged in), var C = g^T Sigma g; 9 predictions; lower = mean - z sigma;
  - 'sample': n Monte-Carlo draws of all four inputs; lower = the (1 - level) quantile;
    draws with no balance count as capacity 0 (the conservative reading).
`lower_N` is what a conservative behaviour should compare the tension with (capacity_node
could publish it next to the capacity; see lab_README.md).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rftgls_core.rft.media import custom_medium
from rftgls_core.types import AnchorState

from .predict import make_predictor

Z_ONE_SIDED = {0.90: 1.2816, 0.95: 1.6449, 0.99: 2.3263}


@dataclass(frozen=True)
class CapacityBand:
    mean_N: float
    std_N: float
    lower_N: float
    upper_N: float
    level: float
    mode: str
    n_predictions: int


def capacity_band(robot: str, xi_n: float, mu_surf: float, cov: np.ndarray,
                  state: AnchorState, phi: float, pull: str,
                  h_sigma_m: float = 0.0, theta_b_sigma_rad: float = 0.0,
                  method: str = 'twist-mesh', mode: str = 'linear', level: float = 0.95,
                  n_samples: int = 64, seed: int = 0) -> CapacityBand:
    """Capacity (N) along d(phi) with a one-sided `level` lower bound and the symmetric upper."""
    cache: dict = {}

    def cap(xi: float, mu: float, h: float, tb: float) -> float:
        key = (round(xi, 3), round(mu, 6))
        if key not in cache:
            cache[key] = make_predictor(method, robot, custom_medium(xi_n=max(xi, 1.0),
                                                                     mu_surf=max(mu, 0.0)))
        r = cache[key].predict(AnchorState(h, tb, state.theta_l1, state.theta_l2), phi, pull)
        return float(r.capacity_N) if r.status.has_value and r.capacity_N is not None else 0.0

    cov = np.asarray(cov, float)
    Sigma = np.zeros((4, 4))
    Sigma[:2, :2] = cov
    Sigma[2, 2], Sigma[3, 3] = h_sigma_m ** 2, theta_b_sigma_rad ** 2
    x0 = np.array([xi_n, mu_surf, state.h, state.theta_b])
    if mode == 'linear':
        c0 = cap(*x0)
        sig = np.sqrt(np.diag(Sigma))
        g = np.zeros(4)
        n = 1
        for i in range(4):
            if sig[i] == 0.0:
                continue
            e = np.zeros(4)
            e[i] = sig[i]
            g[i] = (cap(*(x0 + e)) - cap(*(x0 - e))) / (2.0 * sig[i])
            n += 2
        std = math.sqrt(max(float(g @ Sigma @ g), 0.0))
        z = Z_ONE_SIDED.get(level) or _z(level)
        return CapacityBand(c0, std, c0 - z * std, c0 + z * std, level, mode, n)
    if mode == 'sample':
        rng = np.random.default_rng(seed)
        draws = rng.multivariate_normal(x0, Sigma, size=n_samples, method='svd')
        c = np.array([cap(*d) for d in draws])
        return CapacityBand(float(c.mean()), float(c.std(ddof=1)),
                            float(np.quantile(c, 1.0 - level)), float(np.quantile(c, level)),
                            level, mode, n_samples)
    raise ValueError(f"mode must be 'linear' or 'sample', got {mode!r}")


def _z(level: float) -> float:
    from scipy import stats
    return float(stats.norm.ppf(level))
