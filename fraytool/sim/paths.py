"""Keyframed paths of kinematic bodies: positions and orientations through keys, linear or Catmull-Rom.

A path is a list of keys at strictly increasing times t_0 < ... < t_{n-1}; before t_0 the body holds
the first key and after t_{n-1} the last (docs/scene-format.md, [[bodies]]). Between two keys:

linear        positions by linear interpolation (np.interp, as paths always were); orientations by
              slerp, q(t) = q_i (q_i* q_{i+1})^u with u = (t - t_i) / (t_{i+1} - t_i) (Shoemake 1985,
              "Animating rotation with quaternion curves", SIGGRAPH), the short way round.
catmull_rom   the time-parameterised Catmull-Rom spline through the keys, by the pyramid of Barry &
              Goldman 1988 ("A recursive evaluation algorithm for a class of Catmull-Rom splines",
              SIGGRAPH), whose knots are the key times themselves:

                  A_j   = blend(P_j, P_{j+1}, (t - t_j) / (t_{j+1} - t_j))        j = i-1, i, i+1
                  B_j   = blend(A_j, A_{j+1}, (t - t_j) / (t_{j+2} - t_j))        j = i-1, i
                  C     = blend(B_{i-1}, B_i, (t - t_i) / (t_{i+1} - t_i))        t_i <= t < t_{i+1}

              B_j is Neville's form of the quadratic through keys j..j+2 (Lagrange), and C blends the
              two quadratics of the segment's four keys: the curve passes through every key, its
              velocity at key i is the derivative of the quadratic through keys i-1, i, i+1 from
              either side (C1), and keys sampled from a quadratic motion give that motion exactly,
              at any key spacing. A first or last segment, which has one neighbour key only, is its
              one quadratic (B); a path of two keys is linear. For positions blend is the linear
              interpolation; for orientations it is slerp, the pyramid's lerps replaced by slerps as
              Shoemake 1985 does for Bezier curves, so keys about one fixed axis turn exactly as the
              Euclidean spline of their angles.

Orientation keys are unit quaternions (w, x, y, z), made sign-consistent along the path (each key on the
same side as the one before, q and -q being one rotation), so every segment turns the short way: key a
full turn in steps below 180 degrees.

A kinematic body's velocities over a step are the interpolant's move over that step divided by dt
(fraytool.sim.rigid): linear, the chord; angular, the rotation vector of R(t + dt) R(t)^T over dt
(`angular_velocity_rad_s`), so contacts and friction see exactly the move the path makes.
"""
from __future__ import annotations

import math
from typing import Callable, Sequence

import numpy as np

from fraytool.geometry.rotations import (quat_conjugate, quat_exp, quat_from_euler_deg, quat_log,  # noqa: F401
                                          quat_multiply, quat_to_matrix, slerp)
from fraytool.kinds import INTERPOLATION_NAMES

LINEAR, CATMULL_ROM = INTERPOLATION_NAMES


def orientation_keys(rows: Sequence[Sequence[float]], euler_deg: bool) -> np.ndarray:
    """Keys (t, w, x, y, z), shape (K, 5), from rows (t, rx, ry, rz) Euler degrees (euler_deg) or
    (t, w, x, y, z) quaternions (any non-zero length): normalised and sign-consistent (module docstring)."""
    rows = np.asarray(rows, float).reshape(-1, 4 if euler_deg else 5)
    out = np.empty((rows.shape[0], 5))
    out[:, 0] = rows[:, 0]
    for k, row in enumerate(rows):
        q = quat_from_euler_deg(row[1:]) if euler_deg else row[1:] / np.linalg.norm(row[1:])
        if k and float(np.dot(q, out[k - 1, 1:])) < 0.0:
            q = -q
        out[k, 1:] = q
    return out


def angular_velocity_rad_s(q_start: np.ndarray, q_end: np.ndarray, dt_s: float) -> np.ndarray:
    """World-frame angular velocity [rad/s] that turns q_start into q_end in dt_s: the rotation vector
    2 log(q_end q_start*) / dt (the short way)."""
    turn = quat_multiply(q_end, quat_conjugate(q_start))
    if turn[0] < 0.0:
        turn = -turn
    return 2.0 * quat_log(turn) / dt_s


# --- evaluation ---------------------------------------------------------------------------------------

def _lerp(a: np.ndarray, b: np.ndarray, u: float) -> np.ndarray:
    return a + u * (b - a)


def _segment(times: np.ndarray, time_s: float) -> int:
    """Index i of the segment t_i <= time_s < t_{i+1} (time_s inside the keys' span)."""
    return int(np.searchsorted(times, time_s, side="right")) - 1


def catmull_rom(times: np.ndarray, values: np.ndarray, time_s: float,
                blend: Callable[[np.ndarray, np.ndarray, float], np.ndarray]) -> np.ndarray:
    """The Barry-Goldman pyramid (module docstring) at time_s, inside the keys' span, with `blend` the
    linear interpolation (positions) or slerp (orientations)."""
    i = _segment(times, time_s)
    lo, hi = max(i - 1, 0), min(i + 2, len(times) - 1)
    level = {j: blend(values[j], values[j + 1], (time_s - times[j]) / (times[j + 1] - times[j]))
             for j in range(lo, hi)}
    if hi - lo == 1:
        return level[i]  # two keys: the straight segment
    quad = {j: blend(level[j], level[j + 1], (time_s - times[j]) / (times[j + 2] - times[j]))
            for j in range(lo, hi - 1)}
    if len(quad) == 1:
        return next(iter(quad.values()))  # a first or last segment: its one quadratic
    return blend(quad[i - 1], quad[i], (time_s - times[i]) / (times[i + 1] - times[i]))


def path_position_m(keys: np.ndarray, interpolation: str, time_s: float) -> np.ndarray:
    """Position [m] on the keys (t, x, y, z) at time_s, held before the first and after the last."""
    t = keys[:, 0]
    if interpolation == LINEAR:
        return np.array([np.interp(time_s, t, keys[:, 1 + d]) for d in range(3)])
    return _held(keys, time_s) if _outside(t, time_s) else catmull_rom(t, keys[:, 1:], time_s, _lerp)


def path_orientation(keys: np.ndarray, interpolation: str, time_s: float) -> np.ndarray:
    """Unit quaternion on the keys (t, w, x, y, z) at time_s, held before the first and after the last."""
    t = keys[:, 0]
    if _outside(t, time_s):
        return _held(keys, time_s)
    if interpolation == LINEAR:
        i = _segment(t, time_s)
        q = slerp(keys[i, 1:], keys[i + 1, 1:], (time_s - t[i]) / (t[i + 1] - t[i]))
    else:
        q = catmull_rom(t, keys[:, 1:], time_s, slerp)
    return q / np.linalg.norm(q)


def _outside(times: np.ndarray, time_s: float) -> bool:
    return len(times) == 1 or time_s <= times[0] or time_s >= times[-1]


def _held(keys: np.ndarray, time_s: float) -> np.ndarray:
    """The first key's value at or before its time, else the last's."""
    return keys[0, 1:].copy() if time_s <= keys[0, 0] else keys[-1, 1:].copy()
