"""The RFT bodies of one posed robot: which parts touch the sand, how each moves, their wrenches.

At one instant every buried part is a rigid RFT body (rft/engine.BuriedBody, bound at the
tether point p): the base, and each leg. A leg turning at rate qdot moves with the base twist
xi plus qdot * J (robot.py), so its wrench is W_leg(xi + qdot J); the base and every leg that
does not turn move with xi alone. RFT is rate independent, so only the direction of each
part's twist matters, and the total wrench is

    W(xi) = W_base(xi) + sum_legs W_leg(xi + qdot_leg J_leg)          (Fx, Fz, My) about p.

A leg and its mirror twin (robot.Leg.twin) at the same joint value and rate give the same
planar wrench, so the pair is evaluated once and counted twice (the burrow gaits keep the
sides together; a walking gait does not, and then each leg is its own body).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rft.base import StressModel
from ..rft.engine import BuriedBody
from .robot import PosedMultibody
from .smooth import smooth_planar


@dataclass
class Part:
    """One buried body. jac: (3,) planar twist per unit joint rate (None for the base);
    rate: its joint rate, rad/s (0 for the base and resting legs); count: how many identical
    parts it stands for (2 for a mirror pair); legs: the leg indices it stands for."""

    body: BuriedBody
    jac: np.ndarray | None
    rate: float
    count: int
    legs: tuple[int, ...]

    @property
    def moving(self) -> bool:
        return self.rate != 0.0

    def wrenches(self, xis: np.ndarray) -> np.ndarray:
        """(K, 3) planar wrenches of the part for base twists xis (K, 3)."""
        t = xis if self.jac is None or self.rate == 0.0 else xis + self.rate * self.jac
        moving = np.any(t != 0.0, axis=1)
        if np.all(moving):
            return self.count * self.body.planar_wrench(t)
        # A part at rest has no RFT force (its wrench is set-valued, support.py decides it).
        out = np.zeros((len(t), 3))
        if np.any(moving):
            out[moving] = self.count * self.body.planar_wrench(t[moving])
        return out

    def smooth_wrenches(self, xis: np.ndarray, eps: float) -> np.ndarray:
        """As `wrenches` with the leading weight ramped over eps (smooth.py)."""
        t = xis if self.jac is None or self.rate == 0.0 else xis + self.rate * self.jac
        return self.count * smooth_planar(self.body, t, eps)

    def torque(self, wrench: np.ndarray) -> float:
        """Torque one servo applies about its joint axis to hold the wrench (N m): the sand
        wrench W on the leg and the servo torque tau balance about the hip, tau = -J . W
        (per leg of the part)."""
        assert self.jac is not None
        return float(-(self.jac @ wrench) / self.count)


class Contact:
    """The buried parts of a posed robot for given leg rates (rad/s, one per leg)."""

    def __init__(self, posed: PosedMultibody, model: StressModel, rates: np.ndarray,
                 backend: str = 'auto'):
        self.posed = posed
        self.rates = np.asarray(rates, dtype=float)
        self.parts: list[Part] = []
        p = posed.ref
        if posed.base is not None:
            body = BuriedBody(posed.base, model, ref=p, backend=backend)
            if body.facets_active:
                self.parts.append(Part(body, None, 0.0, 1, ()))
        done: set[int] = set()
        robot = posed.robot
        for i, facets in enumerate(posed.legs):
            if i in done:
                continue
            twin = robot.legs[i].twin
            pair = (twin is not None and twin not in done and twin != i
                    and posed.q[twin] == posed.q[i] and self.rates[twin] == self.rates[i])
            legs = (i, twin) if pair else (i,)
            done.update(legs)
            if not np.any(facets.centroids[:, 2] < 0.0):
                continue
            body = BuriedBody(facets, model, ref=p, backend=backend)
            self.parts.append(Part(body, posed.jac[i], float(self.rates[i]), len(legs), legs))

    @property
    def any(self) -> bool:
        return bool(self.parts)

    def moving(self) -> list[Part]:
        return [pt for pt in self.parts if pt.moving]

    def resting(self) -> list[Part]:
        return [pt for pt in self.parts if not pt.moving]

    def wrench(self, xis: np.ndarray, parts: list[Part] | None = None) -> np.ndarray:
        """Total planar RFT wrench (K, 3) of `parts` (default all) for base twists (K, 3)."""
        xis = np.atleast_2d(xis)
        out = np.zeros((len(xis), 3))
        for pt in self.parts if parts is None else parts:
            out += pt.wrenches(xis)
        return out

    def moving_at_rest(self) -> np.ndarray:
        """Wrench of the turning legs while the base stands still (xi = 0)."""
        out = np.zeros(3)
        for pt in self.moving():
            out += pt.count * pt.body.planar_wrench(pt.rate * pt.jac)
        return out

    def part_wrenches(self, xi: np.ndarray) -> list[np.ndarray]:
        """Each part's wrench at base twist xi (3,), in self.parts order."""
        return [pt.wrenches(xi[None, :])[0] for pt in self.parts]
