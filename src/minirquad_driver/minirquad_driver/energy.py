"""Energy from INA219 power samples: trapezoid rule on MCU timestamps, never across a gap.

Host arrival times jitter by milliseconds, so only the MCU's stamps are used. A step is
skipped, and counted, when it is not a normal sample interval:

* dt == 0 (a duplicate stamp): ignored;
* the MCU clock went backwards (a reset) or the caller marks a discontinuity (reset notice,
  reconnect): the accumulated energy is kept and the baseline restarts;
* dt > max_gap_s, or dt > gap_factor times the recent typical interval: a gap; its length
  is added to ``missing_s`` and the baseline restarts at this sample.

The uint32 ms counter's wrap is handled by modular differences (see ``mcu_clock``). One or
two dropped samples at 50-100 Hz stay below the gap threshold and are integrated across,
which costs a negligible error
(< 0.01 %, docs/design/minirquad-hardware.md#ina219-power-and-energy).
"""
from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

from .mcu_clock import HALF, WRAP


@dataclass
class EnergyIntegrator:
    """Accumulates energy_j (J) from (t_mcu_ms uint32, power W) samples."""

    max_gap_s: float = 0.5
    gap_factor: float = 5.0
    energy_j: float = 0.0
    integrated_s: float = 0.0
    missing_s: float = 0.0
    gaps: int = 0
    resets: int = 0
    samples: int = 0
    rejected: int = 0
    _last_t: int | None = None
    _last_p: float = 0.0
    _recent_dt: deque = field(default_factory=lambda: deque(maxlen=15))

    def mark_discontinuity(self) -> None:
        """The next sample starts a new baseline (MCU reset notice, link reconnect)."""
        self._last_t = None

    def typical_dt(self) -> float | None:
        if not self._recent_dt:
            return None
        return sorted(self._recent_dt)[len(self._recent_dt) // 2]

    def add(self, t_mcu_ms: int, power_w: float) -> float:
        """Integrate one sample; returns the accumulated energy in J."""
        if not math.isfinite(power_w):
            self.rejected += 1
            self._last_t = None      # a bad sample is a hole: do not bridge it
            return self.energy_j
        self.samples += 1
        if self._last_t is None:
            self._last_t, self._last_p = t_mcu_ms, power_w
            return self.energy_j
        delta = (t_mcu_ms - self._last_t) % WRAP
        if delta == 0:
            return self.energy_j
        if delta >= HALF:
            self.resets += 1
            self._last_t, self._last_p = t_mcu_ms, power_w
            return self.energy_j
        dt = delta * 1e-3
        typical = self.typical_dt()
        limit = self.max_gap_s if typical is None else min(self.max_gap_s,
                                                           self.gap_factor * typical)
        if dt > limit:
            self.gaps += 1
            self.missing_s += dt
        else:
            self.energy_j += 0.5 * (power_w + self._last_p) * dt
            self.integrated_s += dt
        # Gaps go into the median too, so a deliberate rate change is learned within
        # about eight samples while an occasional gap cannot move the median.
        self._recent_dt.append(dt)
        self._last_t, self._last_p = t_mcu_ms, power_w
        return self.energy_j
