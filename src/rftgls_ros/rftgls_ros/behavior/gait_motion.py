"""The leg targets of a planned burrow gait over time: from the legs where the burrow starts,
slew to the retracting pose at the gait's speed, dwell, slew to the final pose, hold.

The robot's SetLegs moves each leg at its servo's speed limit (far above a burrow's slew), so
behavior_node streams this ramp as ``leg_targets`` at its step rate: the legs follow it at the
gait's speed. Angles (theta_L1 proximal, theta_L2 distal) in rad, speed in rad/s, times in s.
"""
from __future__ import annotations

import math

from rftgls_core.multibody.gaits import BURROW_DWELL


def _toward(a: tuple[float, float], b: tuple[float, float], step: float) -> tuple[float, float]:
    """a moved toward b by at most `step` rad per axle (each axle at the same slew)."""
    return tuple(x + max(-step, min(step, y - x)) for x, y in zip(a, b))  # type: ignore


def _span(a: tuple[float, float], b: tuple[float, float]) -> float:
    return max(abs(y - x) for x, y in zip(a, b))


def gait_targets(t: float, start: tuple[float, float], retract: tuple[float, float],
                 final: tuple[float, float], speed: float,
                 dwell: float = BURROW_DWELL) -> tuple[float, float]:
    """(theta_L1, theta_L2) target t s after the burrow started from `start` (module doc)."""
    if not (speed > 0.0 and math.isfinite(speed)):
        raise ValueError(f'gait speed must be > 0 rad/s, got {speed}')
    t = max(0.0, t)
    t_retract = _span(start, retract) / speed
    if t <= t_retract:
        return _toward(start, retract, speed * t)
    t_final = t_retract + dwell
    if t <= t_final:
        return retract
    return _toward(retract, final, speed * (t - t_final))


def gait_duration(start: tuple[float, float], retract: tuple[float, float],
                  final: tuple[float, float], speed: float, dwell: float = BURROW_DWELL) -> float:
    """Time the ramp takes to reach the final pose, s."""
    return (_span(start, retract) + _span(retract, final)) / speed + dwell
