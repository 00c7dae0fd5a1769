"""The ground as the simulator sees it: anchor capacity and slip direction for a pose.

``MapAnchorModel`` (default) answers from an rftgls_core state-space map (the shipped
MiniRQuad map in M90 sand), i.e. the same RFT-GLS prediction capacity_node makes, at ~20 us
per query. ``TableAnchorModel`` is a clearly labelled PLACEHOLDER kept for tests that want
hand-set capacities: per-mode values chosen to reproduce the paper's Fig. 10(b) outcome.

Slip twists here follow rftgls_core: (vx, vz, wy) at p in world axes, wy about +y (so the
body pitch thetaB changes by -wy per unit of travel), scaled so |(vx, vz)| = 1.
"""
from __future__ import annotations

import math
from typing import NamedTuple, Protocol

from rftgls_core.types import AnchorState, Status

from .burrow import TABLE_II


class AnchorPrediction(NamedTuple):
    """capacity: largest tension T (N) the anchor holds along d(phi), None without a value.
    slip_twist: direction of motion of p when it fails, (vx, vz, wy) in world axes with
    |(vx, vz)| = 1 (wy in rad per m of travel). status: see docs/design/architecture.md#statuses."""

    capacity: float | None
    slip_twist: tuple[float, float, float]
    status: Status


class AnchorModel(Protocol):
    def predict(self, state: AnchorState, phi: float) -> AnchorPrediction:
        """Capacity and slip twist for anchor state ``state`` under pull angle ``phi`` (rad)."""
        ...


class TableAnchorModel:
    """PLACEHOLDER ground: capacity from the nearest Table II final pose (see module doc).

    C = C_mode * depth_factor * (1 + k_down * max(0, -phi)), where depth_factor falls
    linearly from 1 at the mode's final depth to 0 at ``h_free`` (legs pulled out), and a
    pose more than ``pose_window`` from every final pose gets body friction only
    (mu_body * m * g). The slip twist points along the pull with an upward pull-out part.
    """

    CAPACITY_N = {'DH': 4.6, 'DL': 2.6, 'SH': 2.7}   # at phi = 0, placeholder values

    def __init__(self, mass_kg: float = 0.296, mu_body: float = 0.4, h_free: float = 0.060,
                 k_down: float = 0.8, pose_window: float = math.radians(15.0)):
        self.mass_kg = mass_kg
        self.mu_body = mu_body
        self.h_free = h_free
        self.k_down = k_down
        self.pose_window = pose_window

    def predict(self, state: AnchorState, phi: float) -> AnchorPrediction:
        if not (state.is_finite() and math.isfinite(phi)):
            return AnchorPrediction(None, (0.0, 0.0, 0.0), Status.INVALID_INPUT)
        slip = _unit_slip(phi)
        friction = self.mu_body * self.mass_kg * 9.81
        best, dist = None, float('inf')
        for name, seq in TABLE_II.items():
            d = math.hypot(state.theta_l1 - seq.final[0], state.theta_l2 - seq.final[1])
            if d < dist:
                best, dist = name, d
        if dist > self.pose_window or state.h >= self.h_free:
            return AnchorPrediction(friction, slip, Status.OK)
        h_final = TABLE_II[best].h
        depth = min(1.0, max(0.0, (self.h_free - state.h) / (self.h_free - h_final)))
        cap = self.CAPACITY_N[best] * depth * (1.0 + self.k_down * max(0.0, -phi))
        return AnchorPrediction(max(friction, cap), slip, Status.OK)


def _unit_slip(phi: float) -> tuple[float, float, float]:
    vx, vz = -math.cos(phi), 0.35
    n = math.hypot(vx, vz)
    # Pulled backwards, the axle end pitches down: positive wy (thetaB falls).
    return (vx / n, vz / n, 2.0)


class MapAnchorModel:
    """RFT-GLS ground from an rftgls_core capacity map (backward pulls: the winch is on the
    MiniRQuad's back). The map answers out_of_range off its grid; the simulated world needs
    an answer everywhere, so its truth there is the nearest grid edge's (the state clamped
    into the grid). Where the map has no value the simulator falls back to body friction."""

    def __init__(self, path=None, pull: str = 'backward'):
        from rftgls_core.maps import CapacityMap, shipped_map_path
        self.path = str(path) if path else str(shipped_map_path('minirquad'))
        self.map = CapacityMap.load(self.path)
        self.pull = pull

    def predict(self, state: AnchorState, phi: float) -> AnchorPrediction:
        res = self.map.query(state, phi, self.pull)
        if res.status.value == 'out_of_range':
            ax = self.map.axes
            state = AnchorState(*(min(max(v, float(ax[n][0])), float(ax[n][-1])) for n, v in
                                  zip(('h', 'theta_b', 'theta_l1', 'theta_l2'),
                                      state.as_tuple())))
            phi = min(max(phi, float(self.map.phis[0])), float(self.map.phis[-1]))
            res = self.map.query(state, phi, self.pull)
        if not res.status.has_value or res.slip_twist is None:
            return AnchorPrediction(None, (0.0, 0.0, 0.0), res.status)
        vx, vz, wy = res.slip_twist
        n = math.hypot(vx, vz)
        if n < 1e-9:  # pure rotation about p: move p a little along the pull instead
            return AnchorPrediction(res.capacity_N, _unit_slip(phi), res.status)
        return AnchorPrediction(res.capacity_N, (vx / n, vz / n, wy / n), res.status)


def default_ground() -> AnchorModel:
    """The RFT-GLS map ground when the shipped map is found, else the placeholder table."""
    try:
        return MapAnchorModel()
    except (OSError, ValueError) as exc:
        import warnings
        warnings.warn(f'RFT-GLS map not available ({exc}); using the placeholder ground table')
        return TableAnchorModel()
