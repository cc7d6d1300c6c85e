"""World and body frames for the kernels: a body at centre c with orientation R (body to world) holds a
point at x_body = R^T (x - c); x_world = c + R x_body; a direction turns as R v. Scalars in and out (no
allocation); each sum in the order the kernels always used (component 0, then 1, then 2)."""
from __future__ import annotations

import numba as nb


@nb.njit(cache=True, inline="always")
def to_body(rot, c, x0, x1, x2):
    """x_body = R^T (x - c) of the point (x0, x1, x2)."""
    d0, d1, d2 = x0 - c[0], x1 - c[1], x2 - c[2]
    return (rot[0, 0] * d0 + rot[1, 0] * d1 + rot[2, 0] * d2,
            rot[0, 1] * d0 + rot[1, 1] * d1 + rot[2, 1] * d2,
            rot[0, 2] * d0 + rot[1, 2] * d1 + rot[2, 2] * d2)


@nb.njit(cache=True, inline="always")
def to_world(rot, c, l0, l1, l2):
    """x_world = c + R l of the body-frame point l."""
    return (c[0] + rot[0, 0] * l0 + rot[0, 1] * l1 + rot[0, 2] * l2,
            c[1] + rot[1, 0] * l0 + rot[1, 1] * l1 + rot[1, 2] * l2,
            c[2] + rot[2, 0] * l0 + rot[2, 1] * l1 + rot[2, 2] * l2)


@nb.njit(cache=True, inline="always")
def rotate(rot, v0, v1, v2):
    """R v: a body-frame direction in the world frame."""
    return (rot[0, 0] * v0 + rot[0, 1] * v1 + rot[0, 2] * v2,
            rot[1, 0] * v0 + rot[1, 1] * v1 + rot[1, 2] * v2,
            rot[2, 0] * v0 + rot[2, 1] * v1 + rot[2, 2] * v2)
