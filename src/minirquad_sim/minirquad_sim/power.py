"""Electrical power of the simulated robot, as the INA219 on the battery line would see it.

P = P_idle + sum over legs [k_free |w| + k_sand |w| d + k_hold d + k_contact [d > 0]]
    + winch power,
with w the leg speed (rad/s) and d the depth of the leg tip below the surface (m): free
motion costs friction, motion through sand costs more the deeper the tip is (RFT stresses
grow with depth), a buried leg costs a holding current that grows with depth, and any leg
pushing on sand costs a constant servo effort.

k_hold and k_contact were calibrated (``calibration.calibrate``) so that the burrowing
energy over 8 s, idle removed, of DH and DL is 1.32 and 1.26 times that of SH, as measured
in the paper (section VI-B, Fig. 10(a)). k_free, k_sand and P_idle are assumptions.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class PowerModel:
    """Watts. battery_v: open-circuit battery voltage V; r_internal: ohm (voltage sag)."""

    p_idle: float = 1.2          # MCU, servo electronics, INA219 (assumption)
    k_free: float = 0.08         # W per rad/s per leg (assumption)
    k_sand: float = 5.0          # W per (rad/s * m) (assumption)
    k_hold: float = 2.4156       # W per m of tip depth per leg, calibrated; see module doc
    k_contact: float = 0.050867  # W per leg touching sand, calibrated; see module doc
    winch_efficiency: float = 0.35
    winch_no_load: float = 0.15  # W while the winch turns
    winch_stall: float = 3.0     # W while stalled under command
    battery_v: float = 7.4
    r_internal: float = 0.15

    def leg_power(self, speeds, depths) -> float:
        return sum(self.k_free * abs(w) + self.k_sand * abs(w) * d + self.k_hold * d
                   + (self.k_contact if d > 0.0 else 0.0)
                   for w, d in zip(speeds, depths))

    def winch_power(self, tension: float, speed: float, stalled: bool) -> float:
        if stalled:
            return self.winch_stall
        if speed == 0.0:
            return 0.0
        return self.winch_no_load + abs(tension * speed) / self.winch_efficiency

    def bus(self, power: float) -> tuple[float, float]:
        """(bus voltage V, current A) for a load drawing ``power`` W from the battery."""
        # V = E - I R and P = V I  ->  I = (E - sqrt(E^2 - 4 R P)) / (2 R)
        e, r = self.battery_v, self.r_internal
        disc = max(0.0, e * e - 4.0 * r * power)
        current = (e - disc ** 0.5) / (2.0 * r)
        return e - current * r, current
