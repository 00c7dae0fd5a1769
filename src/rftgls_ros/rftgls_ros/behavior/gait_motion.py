"""The leg targets of a planned burrow gait over time: from the legs where the burrow starts,
slew to the standing pose the plan's burrow starts from, then to the retracting pose at the
gait's speed, dwell, slew to the final pose, hold.

The plan simulated each gait from standing (rftgls_core.planning.gaits.STAND); a burrow that
starts from where the walk left the legs is another burrow (the final depth depends on the
path, not only the final pose), so the robot stands first: behavior_node holds this ramp at
the standing pose until the measured legs are there (burrow.py, at most STAND_WAIT_S). The
measured legs from standing on are what the burrow's replay simulates (replay.py).

The robot's SetLegs moves each leg at its servo's speed limit (far above a burrow's slew), so
behavior_node streams this ramp as ``leg_targets`` at its step rate: the legs follow it at the
gait's speed. Angles (theta_L1 proximal, theta_L2 distal) in rad, speed in rad/s, times in s.
"""
from __future__ import annotations

import math

from rftgls_core.multibody.gaits import BURROW_DWELL
from rftgls_core.planning.gaits import STAND


def _toward(a: tuple[float, float], b: tuple[float, float], step: float) -> tuple[float, float]:
    """a moved toward b by at most `step` rad per axle (each axle at the same slew)."""
    return tuple(x + max(-step, min(step, y - x)) for x, y in zip(a, b))  # type: ignore


def _span(a: tuple[float, float], b: tuple[float, float]) -> float:
    return max(abs(y - x) for x, y in zip(a, b))


def stand_time(start: tuple[float, float], speed: float,
               stand: tuple[float, float] = STAND) -> float:
    """Time the ramp takes from `start` to the standing pose, s: where the planned burrow
    proper begins."""
    return _span(start, stand) / speed


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
    t_retract = _span(stand, retract) / speed
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
    return (_span(start, stand) + _span(stand, retract) + _span(retract, final)) / speed + dwell
