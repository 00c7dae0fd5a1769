"""Named gaits the host can select on /gait, carried to the MCU as data (SET_GAIT).

Four-leg versions of the MiniRHex Buehler-clock gaits (period, duty, sweep, down, phase
per leg in PL, PR, DL, DR order). Walk timing follows MiniRHex's walk (2 s, duty 0.42,
sweep 40 deg, down 20 deg). MiniRHex's angles grow as its legs walk it forward; the
protocol's grow toe forward (away from p), so its stance centre, 20 deg toe back, is down
-20 deg here, and the clock (gait_clock.cpp) sweeps the toes back in stance.
"""
from __future__ import annotations

import math

from .protocol.messages import GaitKind, SetGait

_WALK = dict(period=2.0, duty=0.42, sweep=math.radians(40.0), down=math.radians(-20.0))

GAITS: dict[str, SetGait] = {
    'stand': SetGait(GaitKind.STAND, down=0.0),
    # Trot: diagonal pairs in antiphase (PL with DR, PR with DL).
    'walk': SetGait(GaitKind.CLOCK, phases=(0.0, 0.5, 0.5, 0.0), **_WALK),
    'reverse': SetGait(GaitKind.CLOCK, phases=(0.0, 0.5, 0.5, 0.0), direction=-1, **_WALK),
    # Bound: front pair against rear pair.
    'bound': SetGait(GaitKind.CLOCK, phases=(0.0, 0.0, 0.5, 0.5), **_WALK),
}
