"""Rotations, written once (fraytool.geometry): rotation matrices (body to world, x_world = R x_body) from
Euler angles and to and from unit quaternions (w, x, y, z), quaternion maths for orientation keys (Hamilton
product, log, exp, slerp), rotation vectors (axis times angle) for angular velocities, and the rotation taking
+y to a normal. NumPy only; tested against plain NumPy forms in tests/test_geometry.py."""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np


def euler_rotation(deg: tuple[float, float, float]) -> np.ndarray:
    """Rotation matrix R = Rz @ Ry @ Rx from x, y, z Euler angles in degrees."""
    ax, ay, az = (math.radians(d) for d in deg)
    cx, sx, cy, sy, cz, sz = math.cos(ax), math.sin(ax), math.cos(ay), math.sin(ay), math.cos(az), math.sin(az)
    rx = np.array([[1, 0, 0], [0, cx, -sx], [0, sx, cx]])
    ry = np.array([[cy, 0, sy], [0, 1, 0], [-sy, 0, cy]])
    rz = np.array([[cz, -sz, 0], [sz, cz, 0], [0, 0, 1]])
    return rz @ ry @ rx


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


# --- quaternions (w, x, y, z), Hamilton product ------------------------------------------------------

def quat_multiply(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product a b: the rotation b, then a."""
    aw, ax, ay, az = a
    bw, bx, by, bz = b
    return np.array([aw * bw - ax * bx - ay * by - az * bz,
                     aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw])


def quat_conjugate(q: np.ndarray) -> np.ndarray:
    """q* = (w, -x, -y, -z), the inverse of a unit quaternion."""
    return np.array([q[0], -q[1], -q[2], -q[3]])


def quat_log(q: np.ndarray) -> np.ndarray:
    """log q of a unit quaternion: the vector (theta / 2) axis, for q = (cos theta/2, sin theta/2 axis)."""
    v = np.asarray(q[1:], float)
    s = float(np.linalg.norm(v))
    if s < 1e-300:
        return np.zeros(3)
    return math.atan2(s, float(q[0])) * v / s


def quat_exp(v: np.ndarray) -> np.ndarray:
    """exp of the pure quaternion (0, v): (cos |v|, sin |v| v / |v|), a unit quaternion."""
    half = float(np.linalg.norm(v))
    if half < 1e-300:
        return np.array([1.0, 0.0, 0.0, 0.0])
    return np.concatenate([[math.cos(half)], math.sin(half) * np.asarray(v, float) / half])


def slerp(a: np.ndarray, b: np.ndarray, u: float) -> np.ndarray:
    """Spherical linear interpolation a (a* b)^u = a exp(u log(a* b)) (Shoemake 1985); u outside [0, 1]
    extrapolates along the same great circle (the Catmull-Rom pyramid needs it)."""
    return quat_multiply(a, quat_exp(u * quat_log(quat_multiply(quat_conjugate(a), b))))


def quat_from_euler_deg(deg: Sequence[float]) -> np.ndarray:
    """The unit quaternion of x, y, z Euler angles [degrees] with the convention of rotation_deg,
    R = Rz Ry Rx (fraytool.sim.builder.euler_rotation): q = qz qy qx, q_axis = (cos a/2, sin a/2 axis)."""
    qx, qy, qz = (np.concatenate([[math.cos(math.radians(a) / 2)], math.sin(math.radians(a) / 2) * e])
                  for a, e in zip(deg, np.eye(3)))
    return quat_multiply(qz, quat_multiply(qy, qx))


def quat_to_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a unit quaternion (w, x, y, z) (body to world)."""
    w, x, y, z = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                     [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                     [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])


def rotation_from_y(normal: np.ndarray) -> np.ndarray:
    """A rotation taking +y to the unit vector `normal`."""
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    helper = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    x = np.cross(n, helper)
    x /= np.linalg.norm(x)
    z = np.cross(x, n)
    return np.stack([x, n, z], axis=1)
