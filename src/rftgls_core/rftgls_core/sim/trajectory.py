"""Quasi-static trajectories of a slipping anchor (paper section IV).

While the pull exceeds the capacity the anchor slips, the load stays on the limit curve and
the robot moves along the slip twist. With p = (x, z) the winch point in the world sagittal
plane and thetaB the body pitch:

    d(x, z)/ds = (vx, vz),   d(thetaB)/ds = -wy      (wy about +y tilts x_B down)

where (vx, vz, wy) is the slip twist scaled so that p moves one unit of path per unit s (or the
body turns at most 1 deg per mm when p barely translates). Steps of about 1 mm of p, Euler or
Heun (RK2). It stops when the body plate touches the sand, the legs leave it, or no
quasi-static balance exists (the predictor's status says which).
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from ..predictor.protocol import Predictor
from ..surfaces.base import CapacityResult
from ..types import AnchorState, Pull

MAX_TURN_PER_STEP = math.radians(1.0)   # rad per step when p hardly translates


@dataclass(frozen=True)
class TrajectoryPoint:
    s_m: float                 # path length of p so far, m
    x_m: float                 # winch point in the world sagittal plane, m
    z_m: float                 # = h, m
    theta_b: float             # rad
    force_N: float | None      # pull force on the limit curve (capacity), N
    status: str


@dataclass
class Trajectory:
    points: list[TrajectoryPoint] = field(default_factory=list)
    stop_reason: str = ''

    def as_array(self) -> np.ndarray:
        """(K, 5): s, x, z, thetaB, force (NaN where no value)."""
        return np.array([[p.s_m, p.x_m, p.z_m, p.theta_b,
                          np.nan if p.force_N is None else p.force_N] for p in self.points])


def _rate(result: CapacityResult) -> np.ndarray | None:
    """d(x, z, thetaB)/ds from a slip twist, or None when there is no usable twist."""
    if not result.status.has_value or result.slip_twist is None:
        return None
    vx, vz, wy = result.slip_twist
    speed = math.hypot(vx, vz)
    norm = max(speed, abs(wy) * 1e-3 / MAX_TURN_PER_STEP)
    if norm <= 0.0:
        return None
    return np.array([vx, vz, -wy]) / norm


def simulate_pull(predictor: Predictor, state: AnchorState, phi: float, pull: Pull | str,
                  plate_min_z: Callable[[AnchorState], float], step: float = 1e-3,
                  integrator: str = 'heun', max_travel: float = 0.1,
                  progress: Callable[[int], None] | None = None) -> Trajectory:
    """Integrate the slip of an anchor held at the capacity along a steady tether angle phi.

    plate_min_z(state): lowest point of the body plate (m); the run stops when it reaches 0.
    step: path length of p per step, m. max_travel: path length cap, m.
    """
    if integrator not in ('euler', 'heun'):
        raise ValueError(f"integrator must be 'euler' or 'heun', got {integrator!r}")
    if not (step > 0.0 and math.isfinite(step)):
        raise ValueError(f'step must be a positive length in m, got {step}')
    traj = Trajectory()
    x, q = 0.0, np.array([state.h, state.theta_b])
    s = 0.0
    legs = (state.theta_l1, state.theta_l2)

    def at(z: float, tb: float) -> AnchorState:
        return AnchorState(z, tb, *legs)

    k = 0
    while True:
        st = at(q[0], q[1])
        res = predictor.predict(st, phi, pull)
        traj.points.append(TrajectoryPoint(s, x, q[0], q[1], res.capacity_N, res.status.value))
        if plate_min_z(st) <= 0.0:
            traj.stop_reason = 'body plate reached the surface'
            break
        k1 = _rate(res)
        if k1 is None:
            traj.stop_reason = (f'no quasi-static balance: {res.status.value}'
                                + (f' ({res.reason})' if res.reason else ''))
            break
        if s >= max_travel - 1e-12:
            traj.stop_reason = f'travel cap of {max_travel * 1e3:.0f} mm reached'
            break
        h = min(step, max_travel - s)
        if integrator == 'euler':
            delta = h * k1
        else:
            mid = predictor.predict(at(q[0] + h * k1[1], q[1] + h * k1[2]), phi, pull)
            k2 = _rate(mid)
            delta = h * (0.5 * (k1 + k2) if k2 is not None else k1)
        x += delta[0]
        q = q + delta[1:]
        s += h
        k += 1
        if progress:
            progress(k)
    return traj
