"""Closest points of two segments: a numba kernel shared by the yarn contact (fraytool.sim.tearing)
and the self-collision response (fraytool.collision.response). Scalars in, scalars out."""
from __future__ import annotations

import numba as nb


@nb.njit(cache=True, fastmath=False)
def segment_closest_params(pax, pay, paz, qax, qay, qaz, pbx, pby, pbz, qbx, qby, qbz):
    """Parameters (t_a, t_b) in [0, 1] of the closest points of segments p_a q_a and p_b q_b
    (Ericson 2005, §5.1.9; parallel segments take t_a = 0)."""
    d1x, d1y, d1z = qax - pax, qay - pay, qaz - paz
    d2x, d2y, d2z = qbx - pbx, qby - pby, qbz - pbz
    rx, ry, rz = pax - pbx, pay - pby, paz - pbz
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    eps = 1e-30
    if a <= eps and e <= eps:
        return 0.0, 0.0  # both degenerate to points
    if a <= eps:
        return 0.0, min(max(f / e, 0.0), 1.0)
    c = d1x * rx + d1y * ry + d1z * rz
    if e <= eps:
        return min(max(-c / a, 0.0), 1.0), 0.0
    b = d1x * d2x + d1y * d2y + d1z * d2z
    denom = a * e - b * b
    ta = min(max((b * f - c * e) / denom, 0.0), 1.0) if denom > 0.0 else 0.0
    tb = (b * ta + f) / e
    if tb < 0.0:
        tb = 0.0
        ta = min(max(-c / a, 0.0), 1.0)
    elif tb > 1.0:
        tb = 1.0
        ta = min(max((b - c) / a, 0.0), 1.0)
    return ta, tb
