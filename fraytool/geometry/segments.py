"""Closest points of two segments in plain floating point (numba kernels): the one routine of fraytool.

Used by the CCD search only to *choose* a separating direction and to measure the distance at
a candidate contact time (acceptance); the discards never depend on its rounding.

For segments p(u) = p0 + u (p1 - p0) and q(v) = q0 + v (q1 - q0), u, v in [0, 1], the squared
distance |p(u) - q(v)|^2 is a convex quadratic; its minimiser is the unconstrained one clamped
to the square, re-solved along the side it is clamped to (Lumelsky 1985, "On fast computation of
distance between line segments", IPL 21(2); also Ericson 2005, "Real-Time Collision Detection",
§5.1.9). An exact minimiser satisfies the KKT conditions, so with n = p(u*) - q(v*):
n . (p(u) - q(v)) >= |n|^2 for all (u, v) in [0, 1]^2 (n is a separating direction).
"""
from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True, fastmath=False, inline="always")
def _clamp01(x: float) -> float:
    return min(max(x, 0.0), 1.0)


@numba.njit(cache=True, fastmath=False)
def segment_closest_params(pax, pay, paz, qax, qay, qaz, pbx, pby, pbz, qbx, qby, qbz):
    """Parameters (u, v) in [0, 1] of the closest points of segments p_a q_a and p_b q_b [m], scalars
    in (no allocation): the one closest-points routine of fraytool, used by the yarn contact at mass
    couples, the self-collision response and the CCD. Parallel segments take u = 0."""
    d1x = qax - pax
    d1y = qay - pay
    d1z = qaz - paz
    d2x = qbx - pbx
    d2y = qby - pby
    d2z = qbz - pbz
    rx = pax - pbx
    ry = pay - pby
    rz = paz - pbz
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    if a <= 0.0 and e <= 0.0:
        return 0.0, 0.0  # two points
    if a <= 0.0:
        return 0.0, _clamp01(f / e)  # p is a point
    c = d1x * rx + d1y * ry + d1z * rz
    if e <= 0.0:
        return _clamp01(-c / a), 0.0  # q is a point
    b = d1x * d2x + d1y * d2y + d1z * d2z
    denom = a * e - b * b
    # (nearly) parallel: any u works; take u = 0 and let the clamping below fix v and u
    u = _clamp01((b * f - c * e) / denom) if denom > 1e-14 * a * e else 0.0
    v = (b * u + f) / e
    if v < 0.0:
        return _clamp01(-c / a), 0.0
    if v > 1.0:
        return _clamp01((b - c) / a), 1.0
    return u, v


@numba.njit(cache=True, fastmath=False)
def segment_closest_params_rows(seg: np.ndarray) -> tuple[float, float]:
    """(u, v) of the closest points of segments seg[0] seg[1] and seg[2] seg[3], seg (4, 3) [m]."""
    return segment_closest_params(seg[0, 0], seg[0, 1], seg[0, 2], seg[1, 0], seg[1, 1], seg[1, 2],
                                  seg[2, 0], seg[2, 1], seg[2, 2], seg[3, 0], seg[3, 1], seg[3, 2])
