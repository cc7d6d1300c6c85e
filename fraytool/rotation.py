"""Rotation matrices as unit quaternions (the USD export's xformOp:orient, motion blur's slerp) and
rotation vectors (the axis times the angle, for angular velocities). NumPy only, no pxr; a leaf that
the export and the renderer both use."""
from __future__ import annotations

import numpy as np


def quaternion_wxyz(rotation: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix R (x_world = R x_local), by Shepperd's method."""
    R = np.asarray(rotation, dtype=np.float64)
    t = np.trace(R)
    if t > 0.0:
        s = 2.0 * np.sqrt(t + 1.0)
        q = [0.25 * s, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s]
    elif R[0, 0] > R[1, 1] and R[0, 0] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        q = [(R[2, 1] - R[1, 2]) / s, 0.25 * s, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s]
    elif R[1, 1] > R[2, 2]:
        s = 2.0 * np.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        q = [(R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, 0.25 * s, (R[1, 2] + R[2, 1]) / s]
    else:
        s = 2.0 * np.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        q = [(R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, 0.25 * s]
    q = np.asarray(q)
    return q / np.linalg.norm(q)


def rotation_vector(rotation: np.ndarray) -> np.ndarray:
    """The rotation vector (unit axis times angle [rad], the angle in [0, pi]) of a rotation matrix: the
    logarithm map of SO(3), taken through the quaternion q = (cos a/2, sin a/2 axis) as
    2 atan2(|q_xyz|, q_w) q_xyz / |q_xyz| (accurate for small angles and near pi alike)."""
    q = quaternion_wxyz(rotation)
    if q[0] < 0.0:
        q = -q                       # the same rotation; this sign gives the angle in [0, pi]
    sin_half = float(np.linalg.norm(q[1:]))
    if sin_half < 1e-15:
        return np.zeros(3)
    return 2.0 * np.arctan2(sin_half, q[0]) * q[1:] / sin_half
