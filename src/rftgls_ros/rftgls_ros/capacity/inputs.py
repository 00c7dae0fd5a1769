"""Pure conversions and plausibility checks of capacity_node's sensor inputs (no ROS).

Angles in rad, accelerations in m/s^2, quaternions (x, y, z, w) of the body in a z-up world
(frames and signs: rftgls_conventions). The rules and their
tolerances are explained in docs/design/capacity-inputs.md.
"""
from __future__ import annotations

import math

# The conversions themselves live in rftgls_conventions (one place for every package);
# re-exported here for the estimator's callers.
from rftgls_conventions import (  # noqa: F401
    axle_angle,
    body_z_in_world,
    quat_xyzw_to_pitch,
    unit_quat_xyzw,
    world_z_in_body,
    wrap_angle,
)


def gravity_problem(q: tuple[float, float, float, float],
                    accel: tuple[float, float, float] | None,
                    tilt_limit_rad: float) -> str | None:
    """Why an IMU sample's gravity direction is implausible for a robot on sand, or None.

    q: orientation (x, y, z, w); accel: accelerometer reading in the body frame (m/s^2, +g up
    at rest, REP-145), None when the message does not provide it.
    Implausible: the body up axis tilted more than `tilt_limit_rad` from the world up (e.g. an
    IMU mounted or reporting upside down), or a measured specific force whose direction is more
    than `tilt_limit_rad` from where the orientation puts "up" (orientation and accelerometer
    disagree). An all-zero accelerometer vector is treated as "not provided" (drivers without
    one publish zeros). Raises ValueError for an unusable quaternion.
    """
    up = body_z_in_world(*q)
    cos_lim = math.cos(tilt_limit_rad)
    if up[2] < cos_lim:
        tilt = math.degrees(math.acos(max(-1.0, min(1.0, up[2]))))
        return f'body up axis tilted {tilt:.0f} deg from the vertical'
    if accel is None:
        return None
    a = math.sqrt(sum(c * c for c in accel))
    if not math.isfinite(a):
        return 'accelerometer reading not finite'
    if a < 1e-9:
        return None
    up_body = world_z_in_body(*q)
    cos_a = sum(u * c for u, c in zip(up_body, accel)) / a
    if cos_a < cos_lim:
        ang = math.degrees(math.acos(max(-1.0, min(1.0, cos_a))))
        return f'accelerometer gravity {ang:.0f} deg from the orientation\'s up'
    return None
