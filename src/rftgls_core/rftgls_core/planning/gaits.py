"""The burrow gaits a planner searches: retracting pose, final pose and leg speed.

A gait is the paper's burrowing sequence (multibody.gaits.BurrowGait): from standing, both
legs of each axle slew to the retracting pose, pause, slew to the final pose and hold until
the 8 s window ends. The planner's gait space is a grid of (retract theta_L1, retract
theta_L2, final theta_L1, final theta_L2, speed); a gait the robot cannot run (a joint outside
its range, a leg through the body, slower than the window: multibody/validate.py) is kept with
its reason and never becomes a candidate.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np

from ..multibody.gaits import (
    BURROW_WINDOW,
    DEFAULT_BURROW_SPEED,
    TABLE_II_BURROWS,
    BurrowGait,
    GaitError,
)
from ..multibody.robot import Multibody

STAND = (0.0, 0.0)   # rad, the standing pose a burrow starts from (simulate burrow's default)


@dataclass(frozen=True)
class GaitPoint:
    """One burrow gait. retract, final: (theta_L1, theta_L2), rad. speed: leg slew, rad/s.
    name: 'DH', 'DL', 'SH' for the paper's modes, '' otherwise."""

    retract: tuple[float, float]
    final: tuple[float, float]
    speed: float = DEFAULT_BURROW_SPEED
    name: str = ''

    def as_array(self) -> np.ndarray:
        """(retract l1, retract l2, final l1, final l2, speed), rad and rad/s."""
        return np.array([*self.retract, *self.final, self.speed], dtype=float)

    @classmethod
    def from_array(cls, a, name: str = '') -> GaitPoint:
        v = [float(x) for x in a]
        return cls((v[0], v[1]), (v[2], v[3]), v[4], name)

    def same_motion(self, other: GaitPoint) -> bool:
        """The same commanded motion (names aside), to 1e-9 rad."""
        return bool(np.allclose(self.as_array(), other.as_array(), rtol=0.0, atol=1e-9))

    def to_json(self) -> dict:
        """Degrees at the edge: retract_deg, final_deg, speed_deg_s (and the mode name)."""
        d: dict = {'retract_deg': [round(math.degrees(v), 6) for v in self.retract],
                   'final_deg': [round(math.degrees(v), 6) for v in self.final],
                   'speed_deg_s': round(math.degrees(self.speed), 6)}
        if self.name:
            d['mode'] = self.name
        return d

    def burrow(self, robot: Multibody, duration: float = BURROW_WINDOW) -> BurrowGait:
        """The simulation's gait (GaitError when it does not fit the window)."""
        return BurrowGait(robot, STAND, self.retract, self.final, speed=self.speed,
                          duration=duration)


@dataclass(frozen=True)
class GaitGrid:
    """Axes of the gait space, degrees and deg/s (the edge units a person writes)."""

    retract_l1_deg: tuple[float, ...]
    retract_l2_deg: tuple[float, ...]
    final_l1_deg: tuple[float, ...]
    final_l2_deg: tuple[float, ...]
    speed_deg_s: tuple[float, ...] = (math.degrees(DEFAULT_BURROW_SPEED),)

    def gaits(self) -> list[GaitPoint]:
        r = math.radians
        return [GaitPoint((r(a), r(b)), (r(c), r(d)), r(s))
                for a, b, c, d, s in itertools.product(
                    self.retract_l1_deg, self.retract_l2_deg, self.final_l1_deg,
                    self.final_l2_deg, self.speed_deg_s)]


# The shipped gait space: proximal legs retracted to -60 or -40 deg, distal to -40 or -20 deg,
# final proximal at -40 or -20 deg and distal at -20, 0 or +30 deg, at the default slew
# (1 rad/s). 24 gaits, plus the paper's three modes; modest because one gait costs seven
# simulations (the spread) and a deep tethered one can take a minute
# (docs/design/burrow-planner.md).
SHIPPED_GRID = GaitGrid((-60.0, -40.0), (-40.0, -20.0), (-40.0, -20.0), (-20.0, 0.0, 30.0))


def table_ii_gaits(speed: float = DEFAULT_BURROW_SPEED) -> list[GaitPoint]:
    """The paper's DH, DL and SH burrows (retract, final from Table II) at `speed` rad/s."""
    r = math.radians
    return [GaitPoint((r(a[0]), r(a[1])), (r(b[0]), r(b[1])), speed, name)
            for name, (a, b) in TABLE_II_BURROWS.items()]


def with_modes(gaits: list[GaitPoint]) -> list[GaitPoint]:
    """The gaits and the paper's modes; a mode that is already a grid gait names it."""
    out = list(gaits)
    for mode in table_ii_gaits():
        for i, g in enumerate(out):
            if g.same_motion(mode):
                out[i] = mode
                break
        else:
            out.append(mode)
    return out


def why_not_runnable(robot: Multibody, gait: GaitPoint) -> str | None:
    """None when the robot can run the gait, else why not (one line)."""
    from ..multibody.validate import check_gait
    try:
        check_gait(robot, gait.burrow(robot))
    except GaitError as exc:
        return str(exc)
    return None
