"""Burrow energy per planned gait, learned from the INA219 over the gait space.

Each gait starts at the energy the burrow simulation predicts for it (the gait map's
``energy_elec_J``, above standby). A measured burrow (INA219 energy above idle, J) gives the
ratio measured / predicted at its gait; the robot's sand, servos and battery make that ratio
vary smoothly over the gait space, so one burrow informs its neighbours too:

    ratio(g) = (sum_i w_i(g) r_i + W_ALL s) / (sum_i w_i(g) + W_ALL)
    w_i(g)   = exp(-d(g, g_i)^2 / (2 LENGTH_RAD^2))

r_i is the running mean of the ratios measured at gait g_i, s their mean over every measured
gait (the robot-wide scale the Table II model uses), d the largest difference of the gaits'
four leg angles (rad). A measured gait keeps its own running mean (EnergyModel's rule). With
LENGTH_RAD 20 deg, the shipped grid's spacing, a gait one step from a measured one gets
weight 0.61 against the robot-wide scale's 1; two steps away 0.14.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .model import EnergyModel

LENGTH_RAD = math.radians(20.0)
W_ALL = 1.0


@dataclass
class GaitEnergyModel(EnergyModel):
    """EnergyModel over gaits: ``ratios`` holds each gait's predicted energy (J, so the
    robot-wide scale is measured / predicted), ``gaits`` its (retract l1, l2, final l1, l2),
    rad."""

    gaits: dict[str, np.ndarray] = field(default_factory=dict)

    def ratio(self, name: str) -> float:
        """measured / predicted expected at gait `name` (1 before any measurement)."""
        if not self.measured:
            return 1.0
        here = self.gaits[name]
        num, den = W_ALL * self.scale(), W_ALL
        for k, v in self.measured.items():
            d = float(np.max(np.abs(self.gaits[k] - here)))
            w = math.exp(-0.5 * (d / LENGTH_RAD) ** 2)
            num += w * v / self.ratios[k]
            den += w
        return num / den

    def estimate(self, mode: str) -> float:
        if mode in self.measured:
            return self.measured[mode]
        return self.ratios[mode] * self.ratio(mode)

    def source(self, mode: str) -> str:
        if mode in self.measured:
            return 'measured'
        return 'predicted x measured ratio nearby' if self.measured else 'predicted'
