"""Conventions every package shares: joint names, leg angles, body pitch, tether direction, units.

ROS-free and dependency-free (math only; the vectorised `*_array` forms import numpy when
called): the bottom package of the stack, so every other package (the ROS-free core, the
driver on the robot, the nodes) imports it without pulling anything heavier. Each conversion exists
here once; frames, units, shapes and component order are stated in every docstring
(docs/design/architecture.md#frames-and-signs explains the choices).

Frames
  world   z up, x horizontal in the sagittal plane pointing from the winch point p toward the
          axles, y left (REP-103 axes). Planar quantities are in the x-z plane.
  body    B: x_B from p toward the axles, z_B up when the robot stands level (REP-103 body).
Angles (rad)
  theta_b   body pitch: elevation of x_B above the horizontal, positive NOSE UP. This is the
            opposite sign of REP-103 pitch (a rotation about +y turns the nose down).
  theta_l1, theta_l2   leg angles of the proximal and distal axle, measured from -z_B about
            the axle; the left and right leg of one axle are combined on the circle.
  phi       tether angle at p: the tension pulls p along d(phi) = (-cos phi, 0, sin phi) in the
            world; phi = 0 horizontal, phi < 0 pulls backward and down.
Quaternions are (x, y, z, w) as in geometry_msgs/Quaternion, rotating body vectors into the
world.
Messages: an error or warning for a person is one line (`one_line`), whatever the library
that raised it printed.
Units: SI inside (m, rad, N, s). Degrees and millimetres appear only at the edges (CLI, ROS
parameters meant for people, logs); convert there with `deg_to_rad` and `mm_to_m`.
Files: every file a person names is read through `safe_read` (regular files, a size limit per
kind, bounded JSON/YAML) and every output written through `safe_write` (a fresh name in the
target folder, fsync, rename over the target; never through a link): docs/design/safe-io.md.
"""
from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

TWO_PI = 2.0 * math.pi
# Gravitational acceleration (m/s^2) of every weight and sled force in the stack (the paper's
# value; standard gravity 9.80665 differs by 0.03 %, far inside the model's error).
G = 9.81

# Leg joints in the MCU's order (protocol LEG_NAMES), as keys without the 'leg_' prefix.
LEG_KEYS = ('proximal_left', 'proximal_right', 'distal_left', 'distal_right')
# sensor_msgs/JointState names of the legs (rad) and of the winch spool (m reeled in).
LEG_JOINT_NAMES = tuple(f'leg_{k}' for k in LEG_KEYS)
WINCH_ROPE_JOINT = 'winch_rope'
JOINT_NAMES = LEG_JOINT_NAMES + (WINCH_ROPE_JOINT,)


# --------------------------------------------------------------------------- units (edges)
def deg_to_rad(deg: float) -> float:
    """Degrees (an edge unit: CLI, human-facing parameters) to rad."""
    return math.radians(deg)


def mm_to_m(mm: float) -> float:
    """Millimetres (an edge unit) to m."""
    return mm * 1e-3


# --------------------------------------------------------------------------- leg angles
def wrap_angle(a: float) -> float:
    """a (rad) wrapped into [-pi, pi); an angle already inside is returned unchanged (bit for
    bit, so wrapping never perturbs a state used as a cache key)."""
    if -math.pi <= a < math.pi:
        return a
    return (a + math.pi) % TWO_PI - math.pi


def axle_angle(left: float, right: float) -> tuple[float, float]:
    """(mean, spread) of the left and right leg of one axle, rad, combined on the circle.

    left, right: leg angles from -z_B about the axle, rad. spread = |wrap(right - left)|, the
    shortest angular distance: -150 deg and +150 deg are 60 deg apart and their mean is 180 deg,
    not 0. The mean is only meaningful when the spread is small: see `axle_angles`.
    """
    d = wrap_angle(right - left)
    return wrap_angle(left + 0.5 * d), abs(d)


@dataclass(frozen=True)
class AxleAngles:
    """theta_l1, theta_l2: per-axle leg angles (rad, wrapped to [-pi, pi)); spread_rad:
    (proximal, distal) left/right disagreement, rad; disagreeing: the axles ('proximal',
    'distal') whose spread exceeds the tolerance (their mean is not a leg angle)."""

    theta_l1: float
    theta_l2: float
    spread_rad: tuple[float, float]
    disagreeing: tuple[str, ...]

    @property
    def agree(self) -> bool:
        return not self.disagreeing


def axle_angles(legs: Mapping[str, float], tolerance_rad: float) -> AxleAngles:
    """Left/right averaging of the four leg angles with the agreement check.

    legs: angle (rad, from -z_B) per LEG_KEYS key ('proximal_left', ...); all four required
    (KeyError otherwise). tolerance_rad: largest left/right spread that still counts as one
    axle angle. Never average two legs that are somewhere else: check `.agree` first.
    """
    w = {k: wrap_angle(legs[k]) for k in LEG_KEYS}
    l1, s1 = axle_angle(w['proximal_left'], w['proximal_right'])
    l2, s2 = axle_angle(w['distal_left'], w['distal_right'])
    bad = tuple(a for a, s in (('proximal', s1), ('distal', s2)) if s > tolerance_rad)
    return AxleAngles(l1, l2, (s1, s2), bad)


def leg_keys_from_joint_names(names) -> dict[str, str]:
    """JointState name -> LEG_KEYS key for the legs among `names` (others are left out)."""
    return {n: n[len('leg_'):] for n in names if n in LEG_JOINT_NAMES}


# --------------------------------------------------------------------------- body pitch
def unit_quat_xyzw(x: float, y: float, z: float, w: float) -> tuple[float, float, float, float]:
    """The quaternion (x, y, z, w) normalised; ValueError when it is not finite or its norm is
    (near) zero, so a garbage orientation never turns into a plausible angle."""
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(n) or n < 1e-6:
        raise ValueError(f'orientation quaternion is not usable (norm {n!r})')
    return x / n, y / n, z / n, w / n


def pitch_to_quat_xyzw(theta_b: float) -> tuple[float, float, float, float]:
    """Body orientation (x, y, z, w), body -> world, for body pitch theta_b (rad, nose up
    positive), no roll or yaw: a rotation of -theta_b about +y (REP-103 pitch = -theta_b)."""
    half = -0.5 * theta_b
    return (0.0, math.sin(half), 0.0, math.cos(half))


def pitch_to_quat_xyzw_array(theta_b):
    """Vectorised `pitch_to_quat_xyzw`: theta_b (...,) rad, nose up positive -> (..., 4)
    quaternions (x, y, z, w), body -> world, no roll or yaw."""
    import numpy as np
    half = -0.5 * np.asarray(theta_b, dtype=float)
    zero = np.zeros_like(half)
    return np.stack([zero, np.sin(half), zero, np.cos(half)], axis=-1)


def pure_pitch_quat_xyzw_to_pitch_array(q):
    """Inverse of `pitch_to_quat_xyzw_array` on the whole circle: (..., 4) quaternions
    (x, y, z, w) of rotations about y only -> theta_b (...,) rad in (-pi, pi], nose up positive.
    Unlike `quat_xyzw_to_pitch` (any rotation, |theta_b| <= pi/2) it ignores x and z: use it only
    where the rotation is a pitch by construction (planar poses)."""
    import numpy as np
    q = np.asarray(q, dtype=float)
    theta = -2.0 * np.arctan2(q[..., 1], q[..., 3])
    return np.pi - np.mod(np.pi - theta, TWO_PI)


def quat_xyzw_to_pitch(x: float, y: float, z: float, w: float) -> float:
    """Body pitch theta_B (rad, nose up positive) from the body -> world quaternion (x, y, z, w).

    theta_B is the elevation of x_B above the horizontal: the world z component of R e_x is
    2 (x z - w y), so theta_B = asin(2 (x z - w y)). Roll and yaw do not change it; inverse
    of `pitch_to_quat_xyzw` for |theta_b| <= pi/2. The quaternion is normalised first;
    ValueError if it is not finite or has (near) zero norm.
    """
    x, y, z, w = unit_quat_xyzw(x, y, z, w)
    return math.asin(max(-1.0, min(1.0, 2.0 * (x * z - w * y))))


def body_z_in_world(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """R e_z: the body z axis in world axes (unit vector), for the body -> world quaternion."""
    x, y, z, w = unit_quat_xyzw(x, y, z, w)
    return (2.0 * (x * z + w * y), 2.0 * (y * z - w * x), 1.0 - 2.0 * (x * x + y * y))


def world_z_in_body(x: float, y: float, z: float, w: float) -> tuple[float, float, float]:
    """R^T e_z: the world up axis in body axes (unit vector; the third row of R)."""
    x, y, z, w = unit_quat_xyzw(x, y, z, w)
    return (2.0 * (x * z - w * y), 2.0 * (y * z + w * x), 1.0 - 2.0 * (x * x + y * y))


# --------------------------------------------------------------------------- tether
def tether_direction_xz(phi: float) -> tuple[float, float]:
    """Unit direction (x, z) in world axes along which the tether pulls p, for tether angle
    phi (rad): (-cos phi, sin phi). The same as rftgls_core.types.pull_direction's force part
    (that one is the 3-vector (Fx, Fz, My) of planar wrench space)."""
    return (-math.cos(phi), math.sin(phi))


def tether_phi_from_xz(x: float, z: float) -> float:
    """Tether angle phi (rad, in (-pi, pi]) of a pull along (x, z) in world axes (any length
    > 0): the inverse of `tether_direction_xz`, atan2(z, -x)."""
    return math.atan2(z, -x)


def tether_phi(h_p: float, h_attach: float, free_length: float) -> float:
    """Tether angle phi (rad) of a taut straight tether from p (height h_p, m) to the sled
    attachment (height h_attach, m) with free_length m between them: asin((h_attach - h_p) /
    length), negative when p is above the attachment. The length is floored at 1 mm."""
    s = (h_attach - h_p) / max(free_length, 1e-3)
    return math.asin(max(-1.0, min(1.0, s)))


# --------------------------------------------------------------------------- messages
def one_line(text: object) -> str:
    """Collapse whitespace (h5py, numpy and rosbags messages span lines); an exception with
    no message gives its type name."""
    line = ' '.join(str(text).split())
    if not line and isinstance(text, BaseException):
        return type(text).__name__
    return line
