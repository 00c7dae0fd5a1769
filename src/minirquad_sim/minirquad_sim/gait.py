"""The Buehler clock (MiniRHex): a leg's desired angle as a piecewise-linear function of time.

Per cycle of length ``period`` the leg sweeps the slow "stance" arc of width ``sweep``
centred on ``down`` during ``duty * period``, then recovers through the remaining
2 pi - sweep in the rest of the cycle. Angles are the protocol's (positive toe forward, away
from p): walking forward (direction +1) the toe sweeps backward under the hip in stance, so
the angle falls, and keeps falling through the recovery (the firmware's gait_clock.cpp).
Angles returned here are unwrapped (the leg turns continuously, one full turn per cycle);
wrap them for display.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

TWO_PI = 2.0 * math.pi


@dataclass(frozen=True)
class BuehlerClock:
    """period s, duty (0, 1), sweep rad (0, 2 pi), down rad (the stance centre), phase
    fraction [0, 1), direction +1 (forward: the angle falls) or -1."""

    period: float
    duty: float
    sweep: float
    down: float
    phase: float = 0.0
    direction: int = 1

    def angle(self, t: float) -> float:
        """Desired unwrapped angle (rad) at time t (s) since the gait started."""
        cycles, tau = divmod(t / self.period + self.phase, 1.0)
        t_slow = self.duty
        start = self.down - 0.5 * self.sweep
        if tau < t_slow:
            theta = start + self.sweep * tau / t_slow
        else:
            theta = (start + self.sweep
                     + (TWO_PI - self.sweep) * (tau - t_slow) / (1.0 - t_slow))
        theta += TWO_PI * cycles
        # theta rises (MiniRHex's own sign); forward in the protocol's sign is its mirror
        # about down.
        return 2.0 * self.down - theta if self.direction > 0 else theta

    def ground_speed(self) -> float:
        """Angular speed on the slow arc, rad/s."""
        return self.sweep / (self.duty * self.period)

    def recovery_speed(self) -> float:
        return (TWO_PI - self.sweep) / ((1.0 - self.duty) * self.period)


def wrap_angle(a: float) -> float:
    """Wrap to (-pi, pi]."""
    w = math.fmod(a + math.pi, TWO_PI)
    if w <= 0.0:
        w += TWO_PI
    return w - math.pi
