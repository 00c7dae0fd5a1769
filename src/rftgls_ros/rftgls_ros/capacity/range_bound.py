"""The part of capacity_node's lower bound that covers the inputs it does not measure.

An assumed or modelled input (docs/design/capacity-inputs.md, "Provenance") is known only to
lie within a range: value +- half-width (its band, or the node's assumed range). The capacity
the stack can count on is then the smallest capacity over that range, scanned at
RANGE_SAMPLES points per input (ends included, clipped to the plausible limits); a point
without a value makes it 0 (somewhere in the range the anchor may hold nothing).

Units SI: h in m, phi in rad, capacities in N. No ROS.
"""
from __future__ import annotations

import math
from collections.abc import Callable, Mapping

from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Status

RANGE_SAMPLES = 5


def range_minimum(predict: Callable[[AnchorState, float], CapacityResult], state: AnchorState,
                  phi: float, ranges: Mapping[str, float], h_limits: tuple[float, float],
                  phi_limit: float) -> float:
    """Smallest capacity (N, >= 0) over h +- ranges['height'] and phi +- ranges['phi'] (each
    only if named), the other state variables as given; h_limits (m) and +-phi_limit (rad)
    clip the scan."""
    hs, phis = [state.h], [phi]
    if 'height' in ranges:
        hs = _linspace(max(h_limits[0], state.h - ranges['height']),
                       min(h_limits[1], state.h + ranges['height']))
    if 'phi' in ranges:
        phis = _linspace(max(-phi_limit, phi - ranges['phi']),
                         min(phi_limit, phi + ranges['phi']))
    best = math.inf
    for h in hs:
        st = AnchorState(h, state.theta_b, state.theta_l1, state.theta_l2)
        for ph in phis:
            r = predict(st, ph)
            if r.status not in (Status.OK, Status.ASSUMED) or r.capacity_N is None:
                return 0.0
            best = min(best, r.capacity_N)
    return max(0.0, best)


def _linspace(lo: float, hi: float, n: int = RANGE_SAMPLES) -> list[float]:
    if hi <= lo:
        return [lo]
    return [lo + (hi - lo) * i / (n - 1) for i in range(n)]
