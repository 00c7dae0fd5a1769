"""Capacity with an uncertainty band: medium-parameter covariance and state noise -> capacity.

Inputs (SI): the medium (xi_n, mu_surf) with their 2x2 covariance (`rftgls calibrate` writes
it into the medium JSON under calibration.covariance), and the 1-sigma noise of the state
estimate (h, thetaB). Two propagations:
  - 'linear': central differences one sigma to each side, var C = g^T Sigma g (9 predictions);
    lower = mean - z sigma (one-sided);
  - 'sample': Monte-Carlo draws of all four inputs; lower = the (1 - level) quantile;
    draws with no balance count as capacity 0 (the conservative reading).
`capacity_lower_bound` is the cheap variant an onboard node uses with a map: state noise by
finite differences of any predictor, the medium as a relative sigma of the capacity.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from statistics import NormalDist

import numpy as np

from .surfaces.base import CapacityResult
from .types import AnchorState


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
    from .predictor.live import RobotPredictor
    from .rft.media import custom_medium
    from .robots.presets import get_robot

    predictors: dict = {}
    rob = get_robot(robot)

    def cap(xi: float, mu: float, h: float, tb: float) -> float:
        key = (round(xi, 3), round(mu, 6))
        if key not in predictors:
            medium = custom_medium(xi_n=max(xi, 1.0), mu_surf=max(mu, 0.0))
            predictors[key] = RobotPredictor(rob, medium, method=method)
        r = predictors[key].predict(AnchorState(h, tb, state.theta_l1, state.theta_l2), phi, pull)
        return float(r.capacity_N) if r.status.has_value and r.capacity_N is not None else 0.0

    sigma = np.zeros((4, 4))
    sigma[:2, :2] = np.asarray(cov, float)
    sigma[2, 2], sigma[3, 3] = h_sigma_m ** 2, theta_b_sigma_rad ** 2
    x0 = np.array([xi_n, mu_surf, state.h, state.theta_b])
    if mode == 'linear':
        c0 = cap(*x0)
        sd = np.sqrt(np.diag(sigma))
        g = np.zeros(4)
        n = 1
        for i in range(4):
            if sd[i] == 0.0:
                continue
            e = np.zeros(4)
            e[i] = sd[i]
            g[i] = (cap(*(x0 + e)) - cap(*(x0 - e))) / (2.0 * sd[i])
            n += 2
        std = math.sqrt(max(float(g @ sigma @ g), 0.0))
        z = NormalDist().inv_cdf(level)
        return CapacityBand(c0, std, c0 - z * std, c0 + z * std, level, mode, n)
    if mode == 'sample':
        rng = np.random.default_rng(seed)
        draws = rng.multivariate_normal(x0, sigma, size=n_samples, method='svd')
        c = np.array([cap(*d) for d in draws])
        return CapacityBand(float(c.mean()), float(c.std(ddof=1)),
                            float(np.quantile(c, 1.0 - level)), float(np.quantile(c, level)),
                            level, mode, n_samples)
    raise ValueError(f"mode must be 'linear' or 'sample', got {mode!r}")


def capacity_lower_bound(predict: Callable[[AnchorState, float], CapacityResult],
                         state: AnchorState, phi: float, capacity_N: float, level: float,
                         h_sigma_m: float, theta_b_sigma_rad: float,
                         capacity_rel_sigma: float) -> float:
    """Lower bound (N) at one-sided confidence `level` of the capacity at `state`.

    lower = C - z sqrt((dC/dh s_h)^2 + (dC/dthetaB s_b)^2 + (r C)^2), clamped at 0, with the
    derivatives by central differences one sigma to each side (4 predictor calls). A
    perturbed state without a value gives 0: if one sigma of state error can lose the anchor,
    nothing should be relied on.
    """
    z = NormalDist().inv_cdf(level)
    var = (capacity_rel_sigma * capacity_N) ** 2
    for field, sigma in (('h', h_sigma_m), ('theta_b', theta_b_sigma_rad)):
        if sigma <= 0.0:
            continue
        x = getattr(state, field)
        up = predict(replace(state, **{field: x + sigma}), phi)
        down = predict(replace(state, **{field: x - sigma}), phi)
        if (not (up.status.has_value and down.status.has_value) or up.capacity_N is None
                or down.capacity_N is None):
            return 0.0
        var += (0.5 * (up.capacity_N - down.capacity_N)) ** 2
    return max(0.0, capacity_N - z * math.sqrt(var))
