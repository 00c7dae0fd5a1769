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


# Raw leg angles (before wrapping) beyond +-LEG_LIMIT_RAD are not readings: the driver sends
# them wrapped to (-pi, pi] (src/minirquad_driver/PROTOCOL.md) and a [0, 2 pi) convention stays
# inside 2 pi, so 2 pi accepts both; 1e300 or 6.28e6 rad would wrap to a plausible angle.
LEG_LIMIT_RAD = 2.0 * math.pi
# An IMU whose up axis is further than this from the vertical is upside down or on its side
# (digging accelerations and the steepest pitch the robot reaches, |theta_B| < 30 deg, stay
# well inside).
IMU_TILT_LIMIT_RAD = math.radians(80.0)
# The sagittal model has one depth per axle. Rolled by r, a leg at |y| = 55 mm (MiniRQuad's
# distal legs, the widest) sits 55 sin r above or below the axle's depth: 10 deg gives 9.6 mm,
# as wide as the widest height uncertainty the stack covers (assumed_height_range_m, 10 mm).
# Beyond it left and right legs are not one state.
IMU_ROLL_LIMIT_RAD = math.radians(10.0)

# A unit quaternion from a real IMU driver is unit to within its number format: the BNO055
# sends int16 components scaled by 2^14 (each rounded by at most 3.1e-5, so the norm is off
# by at most 6.1e-5), a float32 filter by ~1e-7, this stack's bridge (float64 sin/cos) by
# ~1e-16. 1e-3 is 16 times the coarsest of these and still far from what a corrupted or
# mis-scaled message gives (x10, x1e-5, 1e150). Refused, never normalised: the direction of a
# quaternion that is not unit is not evidence of anything. (tf2 refuses |q|^2 off by 1e-2.)
QUAT_NORM_TOLERANCE = 1e-3


def quat_norm_problem(q: tuple[float, float, float, float],
                      tolerance: float = QUAT_NORM_TOLERANCE) -> str | None:
    """Why an orientation quaternion (x, y, z, w) is not a unit quaternion, or None."""
    n = math.sqrt(sum(c * c for c in q)) if all(math.isfinite(c) for c in q) else math.nan
    if not math.isfinite(n):
        return 'orientation quaternion not finite'
    if abs(n - 1.0) > tolerance:
        return f'orientation quaternion norm {n:.6g}, not 1 within {tolerance:g}'
    return None


def roll_rad(q: tuple[float, float, float, float]) -> float:
    """Body roll (rad) of the body -> world quaternion (x, y, z, w): the angle of the world up
    axis, seen in the body frame, about x_B from z_B (atan2(u_y, u_z)); 0 for a pure pitch.
    Raises ValueError for an unusable quaternion."""
    u = world_z_in_body(*q)
    return math.atan2(u[1], u[2])


def imu_problem(q: tuple[float, float, float, float],
                accel: tuple[float, float, float] | None,
                tilt_limit_rad: float, roll_limit_rad: float) -> tuple[str, str] | None:
    """(reason code, why) an IMU sample cannot give the body pitch, or None; judged on the
    raw message, before any normalising.

    malformed: the quaternion is not unit (quat_norm_problem). implausible_roll: |roll| above
    roll_limit_rad: the sagittal model has one depth per axle, and a rolled body buries its
    left and right legs at different depths (the pitch formula would still give a plausible
    number). implausible_gravity: gravity_problem (upside down, on its side, or the
    accelerometer disagreeing with the orientation).
    """
    why = quat_norm_problem(q)
    if why is not None:
        return 'malformed', why
    why = gravity_problem(q, accel, tilt_limit_rad)
    if why is not None:
        return 'implausible_gravity', why
    roll = roll_rad(q)
    if abs(roll) > roll_limit_rad:
        return 'implausible_roll', (f'body rolled {math.degrees(roll):.1f} deg (limit '
                                    f'{math.degrees(roll_limit_rad):.1f} deg)')
    return None


def frame_problem(got: str, expected: str) -> str | None:
    """Why a message's header.frame_id is not the configured frame, or None."""
    if got == expected:
        return None
    return f'frame_id {got!r}, expected {expected!r}'


def band_problem(band: float) -> str | None:
    """Why an input value's uncertainty band (half-width, the value's unit) is unusable, or
    None. NaN is "not stated" (the receiver's own range applies); negative or infinite is
    refused: no range can be scanned for it."""
    if math.isnan(band) or (math.isfinite(band) and band >= 0.0):
        return None
    return f'uncertainty band {band!r} is neither a half-width >= 0 nor NaN (not stated)'
