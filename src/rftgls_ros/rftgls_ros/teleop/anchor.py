"""What teleop knows of the anchor it burrowed: the height of p it sends capacity_node (value,
band, provenance) and whether the measured pitch agrees with the modelled burrow.

- Burrowed (keys 1/2/3): h is the burrow simulation's prediction for that mode and the sled
  the robot burrows tied to (rftgls_core.planning.burrowed.mode_pose, computed once at start),
  sent MODELLED with its band while the legs are at the mode's final pose: capacity_node's
  estimate is then `ok` with provenance `height:modelled`, its lower bound covering the band.
  The prediction is the height of that pose: while the burrow is under way, or when it ends
  short of the pose (a stalled servo, a burrow undone), h is sent ASSUMED.
- Once the legs have held the mode's final pose for `settle_s`, the pitch capacity_node used
  (measured by the IMU) is held against the modelled pitch's band. Outside it the burrow did
  not go as modelled: the disagreement is flagged (screen and log) and, until the next burrow,
  h is sent ASSUMED, so the estimate is `assumed (height)` and not evidence unless the operator
  accepts that assumption (accept_assumed_inputs).
- A mode without a modelled pose (no gait map answers for the sled), or standing: h ASSUMED
  (the mode's Table II mean and spread, or the h_stand parameter).

Units SI: m, rad, s; degrees and millimetres only in the texts.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from rftgls_core.planning.burrowed import BurrowedPose
from rftgls_core.types import Provenance

from ..behavior.config import BehaviorConfig
from ..behavior.model import ANCHOR_MODES

# Legs this close to the final pose are at it (rad, per axle): behavior_node's
# burrow_tolerance_rad, so an operator's burrow and the autonomous one count the same legs as
# arrived and send the same height with the same provenance.
LEG_TOLERANCE_RAD = BehaviorConfig().burrow_tolerance_rad


@dataclass(frozen=True)
class HeightInput:
    """The height of p as sent on winch/height_estimate (m; band NaN: not stated)."""

    value: float
    band: float
    provenance: Provenance
    source: str


def _wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class AnchorTracker:
    """poses: mode -> its modelled BurrowedPose, or why there is none (one line)."""

    def __init__(self, poses: Mapping[str, BurrowedPose | str | None], h_stand: float,
                 settle_s: float = 0.5):
        self.poses = dict(poses)
        self.h_stand = h_stand
        self.settle_s = settle_s
        self.mode: str | None = None
        self.pitch_measured = math.nan
        self.flag: str | None = None      # the pitch disagreement, once found
        self._at_final_since: float | None = None

    # ------------------------------------------------------------------ inputs
    def burrow(self, mode: str | None) -> None:
        """A burrow into `mode` was commanded (None: unburrowed, walking or standing)."""
        self.mode, self.flag, self._at_final_since = mode, None, None
        self.pitch_measured = math.nan

    def legs(self, theta_l1: float, theta_l2: float, t: float) -> None:
        """Axle leg angles (rad) measured at t (s)."""
        if self.mode is None:
            return
        final = ANCHOR_MODES[self.mode].final
        at = all(abs(_wrap(a - b)) <= LEG_TOLERANCE_RAD
                 for a, b in zip((theta_l1, theta_l2), final))
        if not at:
            self._at_final_since = None
        elif self._at_final_since is None:
            self._at_final_since = t

    def settled(self, t: float) -> bool:
        return self._at_final_since is not None and t - self._at_final_since >= self.settle_s

    def pitch(self, theta_b: float, t: float) -> str | None:
        """The measured pitch (rad) at t; returns the flag text when it newly disagrees with
        the modelled pose beyond its band (the caller logs it)."""
        pose = self.pose
        if pose is None or not self.settled(t) or not math.isfinite(theta_b):
            return None
        self.pitch_measured = theta_b
        off = pose.pitch_disagreement(theta_b)
        if off is None or self.flag is not None:
            return None
        self.flag = (f'burrow {self.mode} not as modelled: pitch {math.degrees(theta_b):.1f} deg '
                     f'measured, {math.degrees(pose.theta_b_rad):.1f} +- '
                     f'{math.degrees(pose.theta_b_band_rad):.1f} deg modelled; height now '
                     'sent as assumed')
        return self.flag

    # ------------------------------------------------------------------ outputs
    @property
    def pose(self) -> BurrowedPose | None:
        p = self.poses.get(self.mode) if self.mode else None
        return p if isinstance(p, BurrowedPose) else None

    def height(self) -> HeightInput:
        """What is sent as the height of p now (module doc)."""
        if self.mode is None:
            return HeightInput(self.h_stand, math.nan, Provenance.ASSUMED,
                               'h_stand_m parameter, not burrowed (teleop)')
        pose = self.pose
        if pose is None:
            table = ANCHOR_MODES[self.mode]
            why = self.poses.get(self.mode) or 'no modelled pose'
            return HeightInput(table.h, table.h_band, Provenance.ASSUMED,
                               f'Table II mean of {self.mode} (teleop; {why})')
        at_final = self._at_final_since is not None
        provenance = Provenance.MODELLED if at_final and not self.flag else Provenance.ASSUMED
        return HeightInput(pose.h_m, pose.h_band_m, provenance,
                           pose.source + (' (pitch disagrees)' if self.flag else '')
                           + ('' if at_final else ' (legs not at its final pose)'))

    def line(self) -> str:
        """The anchor's screen line (no number that is not one)."""
        if self.mode is None:
            return f'anchor -   h {1e3 * self.h_stand:.0f} mm assumed (standing)'
        h = self.height()
        band = f' +- {1e3 * h.band:.1f}' if math.isfinite(h.band) else ''
        text = f'anchor {self.mode}   h {1e3 * h.value:.1f}{band} mm {h.provenance}'
        pose = self.pose
        if pose is None:
            return text + f' ({self.poses.get(self.mode) or "no modelled pose"})'
        modelled = (f'{math.degrees(pose.theta_b_rad):.1f}'
                    + (f' +- {math.degrees(pose.theta_b_band_rad):.1f}'
                       if math.isfinite(pose.theta_b_band_rad) else ''))
        measured = (f'{math.degrees(self.pitch_measured):.1f} deg measured'
                    if math.isfinite(self.pitch_measured) else 'not yet checked (settling)')
        return text + f'   pitch {measured}, {modelled} deg modelled'
