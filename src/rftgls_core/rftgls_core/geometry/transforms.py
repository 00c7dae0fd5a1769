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
