"""Anchor slip seen from what the robot measures during a tug (docs/design/tug-safety.md).

MiniRQuad measures neither the height of p nor the sled, so a slipping anchor shows only in
the body pitch (IMU), the leg angles (servo encoders, pushed by the sand) and the tension
(load cell) against the spool (encoder). ``SlipDetector`` compares them with their values at
the start of the taut tug; any rule that fires names the anchor as slipping:

- ``slip_pitch``: body pitch moved more than ``pitch_rad`` from its reference. An anchored
  body does not rotate; a slipping one rotates with the slip twist's wy.
- ``slip_legs``: a leg angle moved more than ``leg_rad`` from its reference (the servos hold
  their set-point, so a change means the sand moved the leg).
- ``slip_tension_drop``: while the spool kept reeling in (at least ``min_reel_m`` since the
  peak), the tension fell more than ``tension_drop`` (fraction) below its peak. A sliding sled
  keeps a steady Coulomb tension; an anchor that gives way loses resistance as it moves.

Units: s, N, m, rad. Pure state, no ROS.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

SLIP_PITCH = 'slip_pitch'
SLIP_LEGS = 'slip_legs'
SLIP_TENSION_DROP = 'slip_tension_drop'


@dataclass(frozen=True)
class SlipEvent:
    reason: str
    detail: str
    peak_tension: float      # N: the largest tension of this tug, what the anchor did hold


@dataclass
class SlipDetector:
    pitch_rad: float = math.radians(1.0)
    leg_rad: float = math.radians(2.0)
    tension_drop: float = 0.15
    min_reel_m: float = 0.003
    taut_tension: float = 0.3
    _pitch0: float | None = field(default=None, init=False)
    _legs0: tuple[float, float] | None = field(default=None, init=False)
    _peak: float = field(default=0.0, init=False)
    _spool_at_peak: float | None = field(default=None, init=False)

    def reset(self) -> None:
        """Forget the references: call when a tug (re)starts on a settled anchor."""
        self._pitch0 = self._legs0 = self._spool_at_peak = None
        self._peak = 0.0

    @property
    def peak_tension(self) -> float:
        return self._peak

    def update(self, tension: float | None, spool: float | None, theta_b: float | None,
               legs: tuple[float, float] | None) -> SlipEvent | None:
        """One observation during a tug; a ``SlipEvent`` when a rule fires, else None."""
        if tension is None or not math.isfinite(tension) or tension < self.taut_tension:
            return None
        # References are taken when the tether first goes taut: before that the anchor is
        # unloaded, so any later change is the load's doing.
        if self._pitch0 is None and theta_b is not None and math.isfinite(theta_b):
            self._pitch0 = theta_b
        if self._legs0 is None and legs is not None:
            self._legs0 = legs
        if tension > self._peak:
            self._peak, self._spool_at_peak = tension, spool
        if theta_b is not None and self._pitch0 is not None:
            d = theta_b - self._pitch0
            if abs(d) > self.pitch_rad:
                return SlipEvent(SLIP_PITCH, f'body pitch moved {math.degrees(d):+.1f} deg '
                                             f'under load', self._peak)
        if legs is not None and self._legs0 is not None:
            d = max(abs(a - b) for a, b in zip(legs, self._legs0))
            if d > self.leg_rad:
                return SlipEvent(SLIP_LEGS, f'leg angle moved {math.degrees(d):.1f} deg '
                                            f'under load', self._peak)
        if (spool is not None and self._spool_at_peak is not None
                and spool - self._spool_at_peak >= self.min_reel_m
                and tension < (1.0 - self.tension_drop) * self._peak):
            return SlipEvent(SLIP_TENSION_DROP,
                             f'tension fell to {tension:.2f} N from {self._peak:.2f} N while '
                             f'{1e3 * (spool - self._spool_at_peak):.0f} mm were reeled in',
                             self._peak)
        return None
