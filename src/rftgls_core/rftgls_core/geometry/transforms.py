"""Rotations with explicit conventions (pytransform3d style: say what the angles mean).

rpy_matrix(roll, pitch, yaw) = Rz(yaw) @ Ry(pitch) @ Rx(roll): extrinsic rotations about the
fixed world x, then y, then z axes (the URDF / ROS convention). Angles in rad; the matrix maps
body-frame vectors to world-frame vectors, active rotation.
"""
from __future__ import annotations

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
