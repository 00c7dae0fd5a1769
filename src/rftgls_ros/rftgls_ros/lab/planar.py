"""Planar poses in the sagittal plane: (x, z, theta) with x horizontal, z up, theta in rad.

theta is the elevation of a frame's x axis above world x (positive from x toward z), which is
the anchor convention for thetaB (positive when the axle end is higher than p). It is a
rotation about world -y; a marker whose x axis is world x and y axis world z (its normal,
marker +z, points at a side camera, i.e. along world -y) has theta = 0.

Arrays are vectorised: every function takes (..., 3) arrays of (x_m, z_m, theta_rad).
"""
from __future__ import annotations

import numpy as np

from rftgls_conventions import (
    pitch_to_quat_xyzw_array,
    pure_pitch_quat_xyzw_to_pitch_array,
)


def compose(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a o b: pose b (given in frame a) expressed in a's parent frame."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    z = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, z, wrap(a[..., 2] + b[..., 2])], axis=-1)


def inverse(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -(c * a[..., 0] + s * a[..., 1])
    z = -(-s * a[..., 0] + c * a[..., 1])
    return np.stack([x, z, -a[..., 2]], axis=-1)


def wrap(theta: np.ndarray) -> np.ndarray:
    """Angles to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(theta, float), 2.0 * np.pi)


def from_marker_transform(T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Planar pose and out-of-plane offset from 4x4 transform(s) between two marker frames.

    T maps points of marker B into marker A (T_A_B). In marker frames x = world x, y = world z
    and z = world -y, so x = T[0,3], z = T[1,3], theta = atan2(T[1,0], T[0,0]); T[2,3] (m) is
    the out-of-plane offset, a health check when both markers should lie in one plane.
    """
    T = np.asarray(T, float)
    pose = np.stack([T[..., 0, 3], T[..., 1, 3], np.arctan2(T[..., 1, 0], T[..., 0, 0])], -1)
    return pose, T[..., 2, 3]


# Planar theta is the body pitch theta_b of rftgls_conventions (x_B raised toward z, a
# rotation about world -y); the quaternion forms live there.
quaternion_from_theta = pitch_to_quat_xyzw_array
theta_from_quaternion = pure_pitch_quat_xyzw_to_pitch_array
