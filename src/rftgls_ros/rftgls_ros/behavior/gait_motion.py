"""The leg targets of a planned burrow gait over time: from the legs where the burrow starts,
slew to the standing pose the plan's burrow starts from, then to the retracting pose at the
gait's speed, dwell, slew to the final pose, hold.

The plan simulated each gait from standing (rftgls_core.planning.gaits.STAND); a burrow that
starts from where the walk left the legs is another burrow (the final depth depends on the
path, not only the final pose), so the robot stands first: behavior_node holds this ramp at
the standing pose until the measured legs rest there (burrow.py, at most LEG_WAIT_S). The
measured legs from there on are what the burrow's replay simulates (replay.py).

The robot's SetLegs moves each leg at its servo's speed limit (far above a burrow's slew), so
behavior_node streams this ramp as ``leg_targets`` at its step rate: the legs follow it at the
gait's speed. For that the ramp's time is its own (`RampClock`): a ramp that ran on the wall
clock would, after any stall (the node, the serial bridge, the MCU), send the legs straight
to where the ramp had got to, at servo speed and along another path than the plan's: a
burrow the plan did not simulate, whose replay answers another pose. Angles (theta_L1
proximal, theta_L2 distal) in rad, speed in rad/s, times in s.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from rftgls_core.multibody.gaits import BURROW_DWELL
from rftgls_core.planning.gaits import STAND


def _toward(a: tuple[float, float], b: tuple[float, float], step: float) -> tuple[float, float]:
    """a moved toward b by at most `step` rad per axle (each axle at the same slew)."""
    return tuple(x + max(-step, min(step, y - x)) for x, y in zip(a, b))  # type: ignore


def leg_span(a: tuple[float, float], b: tuple[float, float]) -> float:
    """The larger of the two axles' angle differences between leg poses a and b, rad."""
    return max(abs(y - x) for x, y in zip(a, b))


def stand_time(start: tuple[float, float], speed: float,
               stand: tuple[float, float] = STAND) -> float:
    """Time the ramp takes from `start` to the standing pose, s: where the planned burrow
    proper begins."""
    return leg_span(start, stand) / speed


def gait_targets(t: float, start: tuple[float, float], retract: tuple[float, float],
                 final: tuple[float, float], speed: float, dwell: float = BURROW_DWELL,
                 stand: tuple[float, float] = STAND) -> tuple[float, float]:
    """(theta_L1, theta_L2) target t s after the burrow started from `start` (module doc)."""
    if not (speed > 0.0 and math.isfinite(speed)):
        raise ValueError(f'gait speed must be > 0 rad/s, got {speed}')
    t = max(0.0, t)
    t_stand = stand_time(start, speed, stand)
    if t <= t_stand:
        return _toward(start, stand, speed * t)
    t -= t_stand
    t_retract = leg_span(stand, retract) / speed
    if t <= t_retract:
        return _toward(stand, retract, speed * t)
    t_final = t_retract + dwell
    if t <= t_final:
        return retract
    return _toward(retract, final, speed * (t - t_final))


def gait_duration(start: tuple[float, float], retract: tuple[float, float],
                  final: tuple[float, float], speed: float, dwell: float = BURROW_DWELL,
                  stand: tuple[float, float] = STAND) -> float:
    """Time the ramp takes to reach the final pose, s."""
    return (leg_span(start, stand) + leg_span(stand, retract)
            + leg_span(retract, final)) / speed + dwell


# s: the most one step advances the ramp. behavior_node steps at 50 Hz (20 ms); a step up to
# 2.5 periods late keeps the gait's speed, a longer gap resumes the ramp where it stopped.
RAMP_STEP_MAX_S = 0.05
# s of ramp the measured legs may lag before the ramp waits for them. A target takes ~40-50
# ms to come back as a measured leg (node step, DDS, bridge, MCU loop, 100 Hz telemetry):
# 1.6-2.9 deg at the default 1 rad/s in the physics demo (4 deg at most, 600 g). Twice that
# is no stall; the catch-up after one is at most this much ramp at servo speed.
RAMP_LEAD_S = 0.1


@dataclass
class RampClock:
    """Time along a streamed ramp, s. It runs with the node's clock except that one step
    advances it at most `max_step_s`, and it stands while the measured legs lag the last
    target by more than `lead_rad` on an axle, for at most `wait_s` at once (legs held by the
    sand or a stalled servo must not stall the burrow: its timeout and replay still apply).
    Legs not measured count as lagging."""

    lead_rad: float
    wait_s: float
    max_step_s: float = RAMP_STEP_MAX_S
    t: float = 0.0
    last_now: float | None = None        # s, node clock: the previous step
    lagging_since: float | None = None   # s, node clock: the legs fell behind then

    def advance(self, now: float, legs: tuple[float, float] | None,
                target: tuple[float, float] | None) -> float:
        """The ramp time of this step at node time `now` (s), the measured legs and the
        target sent last step (rad; None before the first)."""
        dt = 0.0 if self.last_now is None else min(max(now - self.last_now, 0.0),
                                                   self.max_step_s)
        self.last_now = now
        lagging = target is not None and (legs is None
                                          or leg_span(legs, target) > self.lead_rad)
        if not lagging:
            self.lagging_since = None
        elif self.lagging_since is None:
            self.lagging_since = now
        if not lagging or now - self.lagging_since >= self.wait_s:
            self.t += dt
        return self.t
