"""The tether between the winch point p and the sled, as the robot's own sensors see it: the
free length from the spool encoder and the tether angle phi from the heights at both ends.
behavior_node and teleop both publish phi for capacity_node from this one tracker.

Units SI: m, rad; phi as rftgls_conventions.tether_phi (negative when p is above the sled's
attachment). No ROS.
"""
from __future__ import annotations

from dataclasses import dataclass

from rftgls_conventions import tether_phi


@dataclass
class TetherTracker:
    """Free tether length (m) from the winch encoder: rope_length (paid out at start) minus
    what was reeled in since the first reading. Spool jumps larger than ``max_jump`` (an MCU
    reset zeroes its counter) are ignored. The tether angle phi (rad) is estimated from the
    height of p and of the sled attachment, assuming a taut straight tether."""

    rope_length: float = 0.50
    attach_height: float = 0.01
    max_jump: float = 0.2
    _last: float | None = None
    reeled: float = 0.0

    def update(self, spool_position: float) -> None:
        if self._last is not None:
            d = spool_position - self._last
            if abs(d) <= self.max_jump:
                self.reeled += d
        self._last = spool_position

    @property
    def free_length(self) -> float:
        return self.rope_length - self.reeled

    def phi(self, h: float) -> float:
        """Tether angle at p for height h (m) of p: negative when p is above the attachment."""
        return tether_phi(h, self.attach_height, self.free_length)
