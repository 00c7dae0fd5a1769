"""Small typed records shared by every layer: anchor states, planar wrenches and twists, statuses,
provenance.

Frames and signs (docs/design/architecture.md): world z up, free surface z = 0, gravity -z.
Planar quantities live in the sagittal x-z plane with the winch point p as reference:
wrench (Fx, Fz, My) in N and N m, twist (vx, vz, wy) in m/s and rad/s, both in world axes.
"""
from __future__ import annotations

import enum
import math
from dataclasses import dataclass


class Status(str, enum.Enum):
    """How far a prediction can be trusted.

    Value-carrying: OK (every input measured, inside what was computed) and ASSUMED (a value,
    but at least one input came from a parameter or a table instead of a measurement; the
    reason names which). OUT_OF_RANGE: a state outside what was computed (a map's grid, a
    robot's physical range) has no value; there is no clamped or extrapolated answer (the
    old 'extrapolated' status is gone, see README "Statuses").
    """

    OK = 'ok'
    ASSUMED = 'assumed'                # value computed with an assumed (not measured) input
    OUT_OF_RANGE = 'out_of_range'      # state outside what was computed: no value
    UNSUPPORTED = 'unsupported'        # no quasi-static balance: weight too large or no buried leg
    DEGENERATE = 'degenerate'          # surface folds, fit not an ellipsoid, ray hits twice, ...
    STALE = 'stale'                    # inputs older than their timeout
    INVALID_INPUT = 'invalid_input'    # NaN, out of range, malformed

    @property
    def has_value(self) -> bool:
        return self in (Status.OK, Status.ASSUMED)

    def __str__(self) -> str:
        return self.value


class Provenance(str, enum.Enum):
    """Where an input value comes from. Every output built on it carries it: an estimate that
    rests on a modelled or assumed input says so (docs/design/capacity-inputs.md,
    "Provenance")."""

    MEASURED = 'measured'   # read from a sensor of this robot
    MODELLED = 'modelled'   # computed by a model from measurements, with an uncertainty band
    ASSUMED = 'assumed'     # a constant (a parameter, a paper's table), not this robot's state

    def __str__(self) -> str:
        return self.value


@dataclass(frozen=True)
class AnchorState:
    """Anchor state (h, thetaB, thetaL1, thetaL2) of the sagittal robot model.

    h: height of the winch point p above the free surface, m (negative when p is buried).
    theta_b: body pitch, rad; positive when the axle end of the body is higher than p.
    theta_l1, theta_l2: proximal and distal leg angles, rad, measured from -z_B about the axles.
    """

    h: float
    theta_b: float
    theta_l1: float
    theta_l2: float

    @classmethod
    def from_degrees(cls, h_m: float, theta_b_deg: float, theta_l1_deg: float,
                     theta_l2_deg: float) -> 'AnchorState':
        return cls(h_m, math.radians(theta_b_deg), math.radians(theta_l1_deg),
                   math.radians(theta_l2_deg))

    def as_tuple(self) -> tuple[float, float, float, float]:
        return (self.h, self.theta_b, self.theta_l1, self.theta_l2)

    def is_finite(self) -> bool:
        return all(math.isfinite(v) for v in self.as_tuple())


class Pull(str, enum.Enum):
    """Orientation of the C-legs relative to the pull (paper Fig. 3)."""

    FORWARD = 'forward'
    BACKWARD = 'backward'

    def __str__(self) -> str:
        return self.value


def pull_direction(phi: float) -> tuple[float, float, float]:
    """Unit load direction d(phi) in planar wrench space (Fx, Fz, My), phi in rad.

    The tether pulls p along (-cos phi, 0, sin phi) in the world: phi = 0 pulls p horizontally
    away from the body (-x), phi < 0 pulls backward and down. A tether carries no moment at p.
    """
    return (-math.cos(phi), math.sin(phi), 0.0)
