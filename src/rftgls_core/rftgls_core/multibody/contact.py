"""The RFT bodies of one posed robot: which parts touch the sand, how each moves, their wrenches.

At one instant every buried part is a rigid RFT body bound at the tether point p: the base,
and each leg. A leg turning at rate qdot moves with the base twist xi plus qdot * J
(robot.py), so its wrench is W_leg(xi + qdot J); the base and every leg that does not turn
move with xi alone. RFT is rate independent, so only the direction of each part's twist
matters, and the total wrench is

    W(xi) = W_base(xi) + sum_legs W_leg(xi + qdot_leg J_leg)          (Fx, Fz, My) about p.

A leg and its mirror twin (robot.Leg.twin) at the same joint value and rate give the same
planar wrench, so the pair is evaluated once and counted twice (the burrow gaits keep the
sides together; a walking gait does not, and then each leg is its own part). All parts are
evaluated together (evaluate.PackedParts).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..rft.base import StressModel
from .evaluate import PackedParts
from .robot import PosedMultibody


@dataclass(frozen=True)
class Part:
    """One buried part. jac: (3,) planar twist per unit joint rate (None for the base);
    rate: its joint rate, rad/s (0 for the base and resting legs); count: how many identical
    parts it stands for (2 for a mirror pair); legs: the leg indices it stands for."""

    jac: np.ndarray | None
    rate: float
    count: int
    legs: tuple[int, ...]

    @property
    def moving(self) -> bool:
        return self.rate != 0.0

    def torque(self, wrench: np.ndarray) -> float:
        """Torque one servo applies about its joint axis to hold the part's wrench (N m): the
        sand wrench W on the leg and the servo torque tau balance about the hip,
        tau = -J . W (per leg of the part)."""
        assert self.jac is not None
        return float(-(self.jac @ wrench) / self.count)


class Contact:
    """The buried parts of a posed robot for given leg rates (rad/s, one per leg).

    packs: PackedParts already bound for this posed robot and model, by the legs of each
    part (the base's: ()); Contacts of one pose at several rates share it, since the packing
    depends on the rates only through which legs pair up (binding packs took 1.0 of the
    2.4 s the walk benchmark spent in balance.step_balance outside the root search)."""

    def __init__(self, posed: PosedMultibody, model: StressModel, rates: np.ndarray,
                 backend: str = 'auto',
                 packs: dict[tuple[tuple[int, ...], ...], PackedParts] | None = None):
        self.posed = posed
        self.rates = np.asarray(rates, dtype=float)
        self.parts: list[Part] = []
        facets = []
        if posed.base_low < 0.0:
            self.parts.append(Part(None, 0.0, 1, ()))
            facets.append(posed.base)
        done: set[int] = set()
        robot = posed.robot
        for i, f in enumerate(posed.legs):
            if i in done:
                continue
            twin = robot.legs[i].twin
            pair = (twin is not None and twin not in done and twin != i
                    and posed.q[twin] == posed.q[i] and self.rates[twin] == self.rates[i])
            legs: tuple[int, ...] = (i, twin) if pair and twin is not None else (i,)
            done.update(legs)
            if not posed.leg_low[i] < 0.0:
                continue
            self.parts.append(Part(posed.jac[i], float(self.rates[i]), len(legs), legs))
            facets.append(f)
        self.packed = self._pack(facets, model, backend, {} if packs is None else packs)
        self._offsets = np.array([np.zeros(3) if pt.jac is None else pt.rate * pt.jac
                                  for pt in self.parts]).reshape(-1, 3)
        self.moving_mask = np.array([pt.moving for pt in self.parts], dtype=bool)

    def _pack(self, facets: list, model: StressModel, backend: str,
              packs: dict[tuple[tuple[int, ...], ...], PackedParts]) -> PackedParts | None:
        """The parts' facets bound together, from packs when this grouping was bound."""
        if not self.parts:
            return None
        key = tuple(pt.legs for pt in self.parts)
        if key not in packs:
            packs[key] = PackedParts(facets, [pt.count for pt in self.parts], model,
                                     self.posed.ref, backend)
        return packs[key]

    @property
    def any(self) -> bool:
        return bool(self.parts)

    def moving(self) -> list[Part]:
        return [pt for pt in self.parts if pt.moving]

    def resting(self) -> list[Part]:
        return [pt for pt in self.parts if not pt.moving]

    def part_wrenches(self, xs: np.ndarray, eps: float = 0.0, rates: bool = True,
                      creep: float = 0.0) -> np.ndarray:
        """(K, P, 3) wrench of each part for base twists xs (K, 3); rates=False holds every
        leg still (the parts move with the base alone). eps > 0 ramps the leading weight,
        creep > 0 the stress of slow facets (evaluate.py)."""
        assert self.packed is not None
        off = self._offsets if rates else np.zeros_like(self._offsets)
        return self.packed.wrenches(xs, off, eps, creep)

    def wrench(self, xs: np.ndarray, eps: float = 0.0, rates: bool = True) -> np.ndarray:
        """Total planar wrench (K, 3) for base twists xs (K, 3)."""
        return self.part_wrenches(xs, eps, rates).sum(axis=1)

    def moving_at_rest(self) -> tuple[np.ndarray, np.ndarray]:
        """Wrench of the turning legs while the base stands still (xi = 0), and each part's
        (K = 1): (total (3,), per part (P, 3))."""
        per = self.part_wrenches(np.zeros((1, 3)))[0]
        per[~self.moving_mask] = 0.0
        return per.sum(axis=0), per
