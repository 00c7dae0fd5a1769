"""Burrowing sequences of the paper's Table II (Huh et al., RA-L 2023, section VI-B).

Each mode moves the proximal legs to theta_L1 and the distal legs to theta_L2, first to the
"retracting" pose, then to the "final" pose. The body settles to the reported mean final
pitch and height (h = height of p above the surface) over the two phases.
"""
from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass(frozen=True)
class BurrowSequence:
    """retract, final: (theta_L1, theta_L2) in rad; theta_b: final body pitch, rad;
    h: final height of p, m (Table II mean values)."""

    retract: tuple[float, float]
    final: tuple[float, float]
    theta_b: float
    h: float


def _deg(a: float, b: float) -> tuple[float, float]:
    return (math.radians(a), math.radians(b))


TABLE_II: dict[str, BurrowSequence] = {
    'DH': BurrowSequence(_deg(-75, -50), _deg(-40, 30), math.radians(5.0), 0.034),
    'DL': BurrowSequence(_deg(-75, -50), _deg(-40, 0), math.radians(8.9), 0.036),
    'SH': BurrowSequence(_deg(-40, -20), _deg(-40, 30), math.radians(2.4), 0.047),
}
