"""Rotations with explicit conventions (pytransform3d style: say what the angles mean).

rpy_matrix(roll, pitch, yaw) = Rz(yaw) @ Ry(pitch) @ Rx(roll): extrinsic rotations about the
fixed world x, then y, then z axes (the URDF / ROS convention). Angles in rad; the matrix maps
body-frame vectors to world-frame vectors, active rotation.
"""
from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np


def rot_x(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_y(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def rot_z(a: float) -> np.ndarray:
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rpy_matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)


def parse_vector(text: str | None, default: tuple[float, ...], what: str,
                 error: type[ValueError] = ValueError) -> np.ndarray:
    """A URDF-style attribute of space-separated numbers ('0 0 1.5') as a float array of
    len(default), or `default` when the attribute is absent (None). Raises `error` (one line,
    naming `what`) when the text is not len(default) finite numbers."""
    if text is None:
        return np.array(default, dtype=float)
    try:
        v = np.array([float(x) for x in text.split()], dtype=float)
    except ValueError:
        raise error(f'{what}: not numbers: {text!r}') from None
    if v.shape != (len(default),) or not np.all(np.isfinite(v)):
        raise error(f'{what}: need {len(default)} finite numbers, got {text!r}')
    return v


def quat_to_matrix(q: Sequence[float]) -> np.ndarray:
    """Rotation matrix of a quaternion (x, y, z, w); it is normalised first."""
    x, y, z, w = np.asarray(q, dtype=float) / np.linalg.norm(q)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def matrix_to_quat(r: np.ndarray) -> tuple[float, float, float, float]:
    """Quaternion (x, y, z, w), w >= 0, of a rotation matrix (Shepperd's method: the largest
    of the four candidates is divided by, so it stays accurate near 180 deg)."""
    m = np.asarray(r, dtype=float)
    tr = m[0, 0] + m[1, 1] + m[2, 2]
    cands = (tr, m[0, 0], m[1, 1], m[2, 2])
    k = int(np.argmax(cands))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + tr)
        q = ((m[2, 1] - m[1, 2]) / s, (m[0, 2] - m[2, 0]) / s, (m[1, 0] - m[0, 1]) / s, s / 4)
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + m[0, 0] - m[1, 1] - m[2, 2])
        q = (s / 4, (m[0, 1] + m[1, 0]) / s, (m[0, 2] + m[2, 0]) / s, (m[2, 1] - m[1, 2]) / s)
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + m[1, 1] - m[0, 0] - m[2, 2])
        q = ((m[0, 1] + m[1, 0]) / s, s / 4, (m[1, 2] + m[2, 1]) / s, (m[0, 2] - m[2, 0]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + m[2, 2] - m[0, 0] - m[1, 1])
        q = ((m[0, 2] + m[2, 0]) / s, (m[1, 2] + m[2, 1]) / s, s / 4, (m[1, 0] - m[0, 1]) / s)
    sign = -1.0 if q[3] < 0 else 1.0
    x, y, z, w = (sign * float(c) for c in q)
    return (x, y, z, w)
