"""A sled tied to the tether point: the load a burrowing or walking robot drags.

MiniRQuad's winch rope runs from p to a sled lying on the sand behind it (paper sec. VI-C).
Whether that rope was taut while the robot burrowed the paper does not say; it matters, since
the retracting stroke pushes the body forward (docs/design/walk-burrow-physics.md). With a
`Sled` the simulation ties p to it: the rope is just taut when the gait starts, pulls with
stiffness x stretch, and the sled slides toward p (Coulomb) once that reaches mu m g, so the
tension never exceeds it. The rope's pull is taken at the start of each step (explicit: a step
moves p at most `body_step`, stiffness x body_step = 0.2 N at the defaults).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from rftgls_conventions import G, tether_phi_from_xz

SLED_MU = 0.5          # sled on sand, assumed (the simulated robot's and `rftgls demo`'s value)
ROPE_STIFFNESS = 400.0 # N/m, assumed (the simulated robot's rope)
SLED_DISTANCE = 0.5    # m behind p when the gait starts, assumed


@dataclass(frozen=True)
class Sled:
    """mass kg, mu Coulomb friction on the sand, distance m behind p (along -x) at the start,
    height m of the rope's attachment above the surface, stiffness N/m of the rope."""

    mass: float
    mu: float = SLED_MU
    distance: float = SLED_DISTANCE
    height: float = 0.01
    stiffness: float = ROPE_STIFFNESS

    def __post_init__(self) -> None:
        for key in ('mass', 'mu', 'distance', 'stiffness'):
            v = getattr(self, key)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f'sled {key} must be a positive number, got {v}')
        if not (math.isfinite(self.height) and self.height >= 0.0):
            raise ValueError(f'sled height must be >= 0 m, got {self.height}')

    @property
    def friction(self) -> float:
        """The pull that slides the sled, N."""
        return self.mu * self.mass * G

    def describe(self) -> dict:
        return {'mass_kg': self.mass, 'mu': f'{self.mu} (assumed)',
                'distance_m': f'{self.distance} (assumed)',
                'stiffness_N_per_m': f'{self.stiffness} (assumed)'}


class Rope:
    """The rope's state: where the sled is and how long the rope is (m, world x-z)."""

    def __init__(self, sled: Sled, px: float, pz: float):
        self.sled = sled
        self.x = px - sled.distance
        self.z = sled.height
        self.length = math.hypot(px - self.x, pz - self.z)   # just taut
        self.moved = 0.0                                      # sled travel, m

    def pull(self, px: float, pz: float) -> tuple[float, float]:
        """(tension N, tether angle phi rad) on p at (px, pz); slides the sled when the
        stretch's pull exceeds its friction."""
        dx, dz = self.x - px, self.z - pz
        dist = math.hypot(dx, dz)
        tension = self.sled.stiffness * max(0.0, dist - self.length)
        if tension > self.sled.friction:
            # the sled slides along the surface toward p until the rope pulls with its friction
            reach = self.length + self.sled.friction / self.sled.stiffness
            x = px - math.sqrt(max(reach ** 2 - dz ** 2, 0.0))
            self.moved += abs(x - self.x)
            self.x = x
            dx = self.x - px
            dist = math.hypot(dx, dz)
            tension = self.sled.friction
        phi = tether_phi_from_xz(dx, dz) if dist > 0.0 else 0.0
        return tension, phi
