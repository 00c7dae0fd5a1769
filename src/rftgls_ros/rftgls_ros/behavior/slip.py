"""Anchor slip seen from what the robot measures (docs/design/tug-safety.md, "Slip").

MiniRQuad measures neither the height of p nor the sled, so a slipping anchor shows only in
the body pitch (IMU), the leg angles (servo encoders, pushed by the sand) and the tension
(load cell) against the spool (encoder). ``SlipDetector`` compares them with references; any
rule that fires names the anchor as slipping:

- ``slip_pitch``: body pitch moved more than ``pitch_rad`` from the anchor's reference. An
  anchored body does not rotate; a slipping one rotates with the slip twist's wy.
- ``slip_legs``: a leg angle moved more than ``leg_rad`` from the anchor's reference (the
  servos hold their set-point, so a change means the sand moved the leg).
- ``slip_tension_drop``: while the spool kept reeling in (at least ``min_reel_m`` since the
  peak of this pull), the tension fell more than ``tension_drop`` (fraction) below that peak.
  A sliding sled keeps a steady Coulomb tension; an anchor that gives way loses resistance.

The references belong to the anchor (one burrow), not to a tug attempt: the pitch and the leg
angles of the settled, still unloaded anchor as its first tug starts (``settle``; without
that, where the tether first goes taut), kept through link gaps, waits, re-checks and
restarted tugs, so a slip that happened while nobody was looking, even one that began before
the host saw any load, is still measured against where the anchor was (``moved``). Only the
tension-drop rule restarts with every pull (``new_pull``): a braked winch lets the tension
settle, and a restarted tug builds it up again. ``reset`` starts a new anchor (a new burrow).

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
    """reason: the rule's code; peak_tension: the largest tension this anchor held (N);
    pitch_lost: body pitch change from the anchor's reference (rad, signed; 0 without one);
    legs_moved: largest leg angle change from the reference (rad; 0 without one)."""

    reason: str
    detail: str
    peak_tension: float
    pitch_lost: float = 0.0
    legs_moved: float = 0.0


@dataclass
class SlipDetector:
    pitch_rad: float = math.radians(1.0)
    leg_rad: float = math.radians(2.0)
    tension_drop: float = 0.15
    min_reel_m: float = 0.003
    taut_tension: float = 0.3
    # the anchor's: references, the largest tension it held, the slip recorded against it
    _pitch0: float | None = field(default=None, init=False)
    _legs0: tuple[float, float] | None = field(default=None, init=False)
    _anchor_peak: float = field(default=0.0, init=False)
    slipped: SlipEvent | None = field(default=None, init=False)
    # this pull's: the tension peak and the spool there (tension-drop rule)
    _peak: float = field(default=0.0, init=False)
    _spool_at_peak: float | None = field(default=None, init=False)

    def reset(self) -> None:
        """A new anchor (a new burrow): forget every reference and the recorded slip."""
        self._pitch0 = self._legs0 = None
        self._anchor_peak = 0.0
        self.slipped = None
        self.new_pull()

    def new_pull(self) -> None:
        """A tug (re)starts on the same anchor: only the tension-drop reference restarts."""
        self._peak, self._spool_at_peak = 0.0, None

    @property
    def peak_tension(self) -> float:
        """The largest tension this anchor held, N."""
        return self._anchor_peak

    @property
    def has_reference(self) -> bool:
        return self._pitch0 is not None or self._legs0 is not None

    def settle(self, theta_b: float | None, legs: tuple[float, float] | None) -> None:
        """The anchor's reference pose, unless it has one: the burrowed pose before any load
        (rad). A restarted tug on the same anchor keeps the first references."""
        if self._pitch0 is None and theta_b is not None and math.isfinite(theta_b):
            self._pitch0 = theta_b
        if self._legs0 is None and legs is not None:
            self._legs0 = legs

    def held(self, tension: float | None) -> None:
        """The anchor holds this tension now (N; winch braked): it held at least that much."""
        if tension is not None and math.isfinite(tension) and self.has_reference:
            self._anchor_peak = max(self._anchor_peak, tension)

    def record(self, ev: SlipEvent) -> None:
        """The slip is attributed to this anchor (answered by the policy); kept until reset."""
        self.slipped = ev

    def update(self, tension: float | None, spool: float | None, theta_b: float | None,
               legs: tuple[float, float] | None) -> SlipEvent | None:
        """One observation during a tug; a ``SlipEvent`` when a rule fires, else None."""
        if tension is None or not math.isfinite(tension) or tension < self.taut_tension:
            return None
        # Without a settled reference, the pose where the tether first goes taut: before that
        # the anchor is unloaded, so any later change is the load's doing.
        self.settle(theta_b, legs)
        self._anchor_peak = max(self._anchor_peak, tension)
        if tension > self._peak:
            self._peak, self._spool_at_peak = tension, spool
        ev = self.moved(theta_b, legs, 'under load')
        if ev is not None:
            return ev
        if (spool is not None and self._spool_at_peak is not None
                and spool - self._spool_at_peak >= self.min_reel_m
                and tension < (1.0 - self.tension_drop) * self._peak):
            return SlipEvent(SLIP_TENSION_DROP,
                             f'tension fell to {tension:.2f} N from {self._peak:.2f} N while '
                             f'{1e3 * (spool - self._spool_at_peak):.0f} mm were reeled in',
                             self._anchor_peak, *self._lost(theta_b, legs))
        return None

    def moved(self, theta_b: float | None, legs: tuple[float, float] | None,
              when: str) -> SlipEvent | None:
        """The pose rules against the anchor's references, whatever the tension now (after
        a link gap or a wait the load may have eased); None without references. ``when``
        says in the detail when the move was seen."""
        pitch, spread = self._lost(theta_b, legs)
        if abs(pitch) > self.pitch_rad:
            return SlipEvent(SLIP_PITCH, f'body pitch moved {math.degrees(pitch):+.1f} deg '
                                         f'{when}', self._anchor_peak, pitch, spread)
        if spread > self.leg_rad:
            return SlipEvent(SLIP_LEGS, f'leg angle moved {math.degrees(spread):.1f} deg '
                                        f'{when}', self._anchor_peak, pitch, spread)
        return None

    def _lost(self, theta_b: float | None, legs: tuple[float, float] | None
              ) -> tuple[float, float]:
        """(pitch change rad, largest leg change rad) from the anchor's references."""
        pitch = 0.0
        if theta_b is not None and math.isfinite(theta_b) and self._pitch0 is not None:
            pitch = theta_b - self._pitch0
        spread = 0.0
        if legs is not None and self._legs0 is not None:
            spread = max(abs(a - b) for a, b in zip(legs, self._legs0))
        return pitch, spread
