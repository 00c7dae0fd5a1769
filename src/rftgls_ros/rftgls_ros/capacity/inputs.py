"""Pure conversions and plausibility checks of capacity_node's sensor inputs (no ROS).

Angles in rad, accelerations in m/s^2, quaternions (x, y, z, w) of the body in a z-up world
(REP-103 base frame: x forward from p toward the axles, y left, z up). The rules and their
tolerances are explained in docs/design/capacity-inputs.md.
"""
from __future__ import annotations

import math

TWO_PI = 2.0 * math.pi


def wrap_angle(a: float) -> float:
    """a wrapped into [-pi, pi) (rad); an angle already inside is returned unchanged (bit for
    bit, so wrapping never perturbs a state used as a cache key)."""
    if -math.pi <= a < math.pi:
        return a
    return (a + math.pi) % TWO_PI - math.pi


def axle_angle(left: float, right: float) -> tuple[float, float]:
    """(mean, spread) of the two legs of one axle, rad, on the circle.

    The spread is the shortest angular distance |wrap(left - right)|: -150 deg and +150 deg are
    60 deg apart, not 300, and their mean is 180 deg, not 0. The caller decides what a spread
    means; the mean is only meaningful when the spread is small.
    """
    d = wrap_angle(right - left)
    return wrap_angle(left + 0.5 * d), abs(d)


def _unit_quaternion(x: float, y: float, z: float, w: float) -> tuple[float, float, float, float]:
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(n) or n < 1e-6:
        raise ValueError(f'orientation quaternion is not usable (norm {n!r})')
    return x / n, y / n, z / n, w / n


def pitch_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """theta_B (rad) from a body orientation quaternion.

    theta_B is the elevation of the body x axis above the horizontal. The body x axis in the
    world is R e_x, whose z component is 2 (x z - w y); so theta_B = asin(2 (x z - w y)).
    For a pure REP-103 pitch beta (rotation about +y, positive turns the nose DOWN) this gives
    theta_B = -beta: the sign flip between REP-103 pitch and the anchor state's theta_B.
    Roll and yaw do not change it. The quaternion is normalised first; raises ValueError if it
    is not finite or has (near) zero norm.
    """
    x, y, z, w = _unit_quaternion(x, y, z, w)
    return math.asin(max(-1.0, min(1.0, 2.0 * (x * z - w * y))))


def body_up_in_world(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """The body z axis expressed in the world, R e_z (unit vector)."""
    x, y, z, w = _unit_quaternion(x, y, z, w)
    return (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))


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
    up = body_up_in_world(*q)
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
    # World up in body axes: R^T e_z = (R e_z seen from the body) -> the third row of R.
    x, y, z, w = _unit_quaternion(*q)
    up_body = (2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))
    cos_a = sum(u * c for u, c in zip(up_body, accel)) / a
    if cos_a < cos_lim:
        ang = math.degrees(math.acos(max(-1.0, min(1.0, cos_a))))
        return f'accelerometer gravity {ang:.0f} deg from the orientation\'s up'
    return None
