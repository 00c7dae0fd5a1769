"""Winch, rope and sled, quasi-static.

The spool reels rope in at the commanded speed unless the motor stalls. The rope is a stiff
spring: T = k * max(0, distance(p, sled) - free length). A Coulomb sled moves only when T
reaches mu * m * g, so tension never exceeds that (the sled slides at the reel speed). If
the anchor's capacity is below the demanded tension, the robot slips instead and the sled
stops (handled in ``robot.py``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from rftgls_conventions import G, tether_phi_from_xz


@dataclass
class WinchSled:
    """Positions in world x-z (m): sled_x on the surface behind the robot (x < p's x).

    sled_mass kg, sled_mu Coulomb friction coefficient, rope_k N/m, stall_tension N (the
    gearmotor's stall at the spool radius), max_speed m/s.
    """

    sled_x: float = -0.50
    sled_z: float = 0.01        # rope attachment height on the sled
    rope_length: float = 0.50   # rope paid out at start (free length)
    sled_mass: float = 0.400
    sled_mu: float = 0.5   # assumed sled-on-sand friction (same as `rftgls demo`)
    rope_k: float = 400.0
    stall_tension: float = 8.0
    max_speed: float = 0.05
    command: float = 0.0        # reel-in speed set-point, m/s
    spool_position: float = 0.0 # rope reeled in since boot, m
    spool_velocity: float = 0.0
    tension: float = 0.0
    stalled: bool = False
    sled_moving: bool = False

    @property
    def sled_friction(self) -> float:
        return self.sled_mu * self.sled_mass * G

    def free_length(self) -> float:
        return self.rope_length - self.spool_position

    def geometry(self, px: float, pz: float) -> tuple[float, float]:
        """(distance p -> sled attachment, tether angle phi) with d(phi) = (-cos, sin)."""
        dx, dz = self.sled_x - px, self.sled_z - pz
        dist = math.hypot(dx, dz)
        phi = tether_phi_from_xz(dx, dz) if dist > 0 else 0.0
        return dist, phi

    def reel(self, dt: float) -> None:
        """Advance the spool one step (before the rope and anchor are resolved)."""
        v = max(-self.max_speed, min(self.max_speed, self.command))
        self.stalled = v > 0 and self.tension >= self.stall_tension
        if self.stalled:
            v = 0.0
        # Paying out cannot go past the rope end.
        if self.free_length() - v * dt > 2.0:
            v = 0.0
        self.spool_position += v * dt
        self.spool_velocity = v
