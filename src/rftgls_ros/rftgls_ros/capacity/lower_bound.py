"""A conservative capacity: the one-sided lower confidence bound of the prediction.

Two sources of uncertainty, both as 1-sigma inputs:
- the state estimate (h and thetaB): propagated by central differences of the predictor,
  one sigma to each side (4 extra queries; ~20 us each from a map);
- the medium parameters: capacity_rel_sigma, the relative 1-sigma of the capacity they cause
  (RFT stress is proportional to xi_n, so sigma(xi_n)/xi_n of a calibration is the natural
  value; `rftgls calibrate` reports it).

    lower = C - z(level) sqrt((dC/dh s_h)^2 + (dC/dthetaB s_b)^2 + (r C)^2),  clamped at 0

A perturbed state without a value (no balance, off the map edge) gives lower = 0: if one
sigma of state error can lose the anchor, nothing should be relied on.
"""
from __future__ import annotations

import math
from dataclasses import replace
from statistics import NormalDist
from typing import Callable

from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState


def capacity_lower_bound(predict: Callable[[AnchorState, float], CapacityResult],
                         state: AnchorState, phi: float, capacity_N: float, level: float,
                         h_sigma_m: float, theta_b_sigma_rad: float,
                         capacity_rel_sigma: float) -> float:
    """Lower bound (N) at one-sided confidence `level` (e.g. 0.95) of the capacity at state."""
    z = NormalDist().inv_cdf(level)
    var = (capacity_rel_sigma * capacity_N) ** 2
    for field, sigma in (('h', h_sigma_m), ('theta_b', theta_b_sigma_rad)):
        if sigma <= 0.0:
            continue
        x = getattr(state, field)
        up = predict(replace(state, **{field: x + sigma}), phi)
        down = predict(replace(state, **{field: x - sigma}), phi)
        if not (up.status.has_value and down.status.has_value):
            return 0.0
        slope_times_sigma = 0.5 * (up.capacity_N - down.capacity_N)
        var += slope_times_sigma ** 2
    return max(0.0, capacity_N - z * math.sqrt(var))
