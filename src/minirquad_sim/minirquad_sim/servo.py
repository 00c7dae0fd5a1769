"""A leg servo as the firmware drives it: the angle slews toward its target at a speed limit.

MiniRHex runs its servos in velocity mode with a PD loop on angle; at the sample rates the
host sees, that is well approximated by a rate-limited first-order approach.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass
class Servo:
    """angle rad (unwrapped), velocity rad/s, target rad (unwrapped), max_speed rad/s."""

    angle: float = 0.0
    velocity: float = 0.0
    target: float = 0.0
    max_speed: float = 8.0
    gain: float = 25.0     # 1/s: approach rate near the target

    def step(self, dt: float) -> None:
        if dt <= 0.0:
            return
        want = self.gain * (self.target - self.angle)
        v = max(-self.max_speed, min(self.max_speed, want))
        # Do not overshoot the target within one step.
        if abs(v * dt) > abs(self.target - self.angle):
            v = (self.target - self.angle) / dt
        self.angle += v * dt
        self.velocity = v

    def hold(self) -> None:
        """Stop where the leg is (e-stop, watchdog)."""
        self.target = self.angle
        self.velocity = 0.0
