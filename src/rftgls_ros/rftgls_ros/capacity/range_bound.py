"""The part of capacity_node's lower bound that covers the inputs it does not measure.

An assumed or modelled input (docs/design/capacity-inputs.md, "Provenance") is known only to
lie within a range: value +- half-width (its band, or the node's assumed range). The capacity
the stack can count on is then the smallest capacity over that range, scanned at the value
plus SCAN_FRACTIONS of the half-width (five points, ends included, each clipped to the
plausible limits); a point without a value makes it 0 (somewhere in the range the anchor may
hold nothing). The points are the value itself and half-way points on purpose: with a band
of two standard deviations they are the states the prediction and the one-sigma bound ask
for too, which a caller can answer once (CapacityEstimator does).

Units SI: h in m, phi in rad, capacities in N. No ROS.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Status

SCAN_FRACTIONS = (-1.0, -0.5, 0.0, 0.5, 1.0)


def range_minimum(predict: Callable[[AnchorState, float], CapacityResult], state: AnchorState,
                  phi: float, ranges: Mapping[str, float], h_limits: tuple[float, float],
                  phi_limit: float) -> float:
    """Smallest capacity (N, >= 0) over h +- ranges['height'] and phi +- ranges['phi'] (each
    only if named), the other state variables as given; h_limits (m) and +-phi_limit (rad)
    clip the scan."""
    hs, phis = [state.h], [phi]
    if 'height' in ranges:
        hs = scan_points(state.h, ranges['height'], *h_limits)
    if 'phi' in ranges:
        phis = scan_points(phi, ranges['phi'], -phi_limit, phi_limit)
    best = math.inf
    for h in hs:
        st = AnchorState(h, state.theta_b, state.theta_l1, state.theta_l2)
        for ph in phis:
            r = predict(st, ph)
            if r.status not in (Status.OK, Status.ASSUMED) or r.capacity_N is None:
                return 0.0
            best = min(best, r.capacity_N)
    return max(0.0, best)



def scan_points(x: float, half_width: float, lo: float, hi: float) -> list[float]:
    """x + f * half_width for f in SCAN_FRACTIONS, each clipped to [lo, hi], without repeats
    (a zero width is x alone)."""
    return list(dict.fromkeys(min(hi, max(lo, x + f * half_width)) for f in SCAN_FRACTIONS))
