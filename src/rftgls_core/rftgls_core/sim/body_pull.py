"""A rigid anchor body pulled out at a constant tether angle: the paper's Fig. 13 experiment.

The body is posed from a sagittal state, like the robots (docs/design/architecture.md): body
frame B with its origin at the tether point p, x_B along the body away from p; the state's h is
the height of p above the free surface (m) and theta_b the angle of x_B above the horizontal
(rad; negative when the far end is deeper than p). Leg angles are unused (0). A predictor that
answers `predict(state, phi, pull)` with a sagittal CapacityResult can then drive the existing
quasi-static trajectory integrator (sim/trajectory.py) unchanged.

The body must be mirror-symmetric about its x_B-z_B plane (checked per pose by PosedAnchorSolver: an
asymmetric body answers through the 6D path, whose out-of-plane slip a sagittal trajectory
cannot follow; such a pose is reported `invalid_input`, reason `not_sagittal`).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..body import RigidBody
from ..geometry.transforms import rot_y
from ..posed import PosedAnchor, PosedAnchorSolver
from ..surfaces.base import CapacityResult
from ..types import AnchorState, Pull, Status


@dataclass(frozen=True)
class BodyAnchor:
    """A rigid body whose mesh frame is B (tether point at its origin), posed from a state."""

    body: RigidBody

    def pose(self, state: AnchorState) -> PosedAnchor:
        # rot_y(-thetaB): x_B tilts up for positive thetaB, as for the robots.
        pitch = -state.theta_b
        return self.body.pose((0.0, 0.0, state.h), (0.0, pitch, 0.0), (0.0, 0.0, state.h))

    def top_z(self, state: AnchorState) -> float:
        """Highest point of the posed body, m."""
        v = self.body.mesh.vertices @ rot_y(-state.theta_b).T
        return float(v[:, 2].max() + state.h)


class BodyPredictor:
    """predict(state, phi, pull) for a BodyAnchor: the Predictor protocol (predictor.py) with
    the planar slip twist (vx, vz, wy) of the sagittal path. `pull` is ignored (a rigid body
    has no leg orientation)."""

    def __init__(self, anchor: BodyAnchor, solver: PosedAnchorSolver):
        self.anchor = anchor
        self.solver = solver

    def predict(self, state: AnchorState, phi: float, pull: Pull | str = Pull.BACKWARD
                ) -> CapacityResult:
        r = self.solver.solve(self.anchor.pose(state), phi, 0.0)
        if r.status.has_value and r.space != 'sagittal':
            return CapacityResult(phi=phi, status=Status.INVALID_INPUT, method=r.method,
                                  reason='not_sagittal',
                                  detail='the body is not mirror-symmetric about the pull '
                                         'plane: a sagittal trajectory cannot follow it')
        planar: tuple[float, float, float] | None = None
        planar_s: tuple[float, float, float] | None = None
        if r.slip_twist is not None and r.slip_twist_scaled is not None:
            planar, planar_s = _planar(r.slip_twist), _planar(r.slip_twist_scaled)
        cap = r.capacity_N if r.status.has_value else None
        return CapacityResult(phi=phi, status=r.status, method=r.method, capacity_N=cap,
                              slip_twist=planar, slip_twist_scaled=planar_s, reason=r.reason,
                              detail=r.detail, flags=r.flags)


def _planar(twist6) -> tuple[float, float, float]:
    """(vx, vz, wy) of a twist in the x-z plane, renormalised."""
    t = np.asarray(twist6, dtype=float)[[0, 2, 4]]
    t = t / np.linalg.norm(t)
    return (float(t[0]), float(t[1]), float(t[2]))
