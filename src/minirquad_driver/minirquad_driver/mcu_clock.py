"""Unwrapping the MCU's uint32 millisecond clock, and detecting MCU resets.

The MCU counter wraps after 2**32 ms (49.7 days); differences are taken modulo 2**32. A
step "backwards" (a modular difference in the upper half of the range) cannot come from a
serial link that preserves order, so it means the MCU restarted its clock: a reset.
"""
from __future__ import annotations

from dataclasses import dataclass

WRAP = 1 << 32
HALF = 1 << 31


@dataclass
class McuClock:
    """Continuous MCU time (int ms) from wrapped uint32 stamps; counts wraps and resets."""

    last_raw: int | None = None
    unwrapped_ms: int = 0
    wraps: int = 0
    resets: int = 0

    def update(self, raw_ms: int) -> tuple[int, bool]:
        """Feed one stamp; return (unwrapped ms, discontinuity) where discontinuity is True
        when this stamp starts a new time base (first stamp, or a reset)."""
        if self.last_raw is None:
            self.last_raw = raw_ms
            self.unwrapped_ms = raw_ms
            return self.unwrapped_ms, True
        delta = (raw_ms - self.last_raw) % WRAP
        if delta >= HALF:
            self.resets += 1
            self.last_raw = raw_ms
            self.unwrapped_ms = raw_ms
            return self.unwrapped_ms, True
        if raw_ms < self.last_raw:
            self.wraps += 1
        self.last_raw = raw_ms
        self.unwrapped_ms += delta
        return self.unwrapped_ms, False

    def restart(self) -> None:
        """Forget the time base (MCU reset notice, reconnect)."""
        self.last_raw = None
