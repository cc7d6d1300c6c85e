"""The edge-edge coplanarity cubic in Bernstein form, with interval coefficients.

For segments a0 a1 and b0 b1 whose end points move linearly over t in [0, 1], the four points
are coplanar when (Bridson, Fedkiw & Anderson 2002, "Robust treatment of collisions, contact and
friction for cloth animation", SIGGRAPH 2002; docs/method.md §4.2)

    f(t) = r(t) . (p(t) x q(t)) = 0,   p = a1 - a0 (x21),  q = b1 - b0 (x43),  r = b0 - a0 (x31),

and each of p, q, r is linear in t: p(t) = (1 - t) p0 + t p1 with p0, p1 the vectors at the step
start and end. f is a cubic; its Bernstein coefficients on [0, 1] are the values of its blossom
(polar form) ``B(t1, t2, t3) = 1/6 sum over permutations of r(t_i) . (p(t_j) x q(t_k))``:

    3 c0 = 3 r0.(p0 x q0)
    3 c1 = r1.(p0 x q0) + r0.(p1 x q0) + r0.(p0 x q1)
    3 c2 = r0.(p1 x q1) + r1.(p0 x q1) + r1.(p1 x q0)
    3 c3 = 3 r1.(p1 x q1)

We keep ``b_i = 3 c_i`` (no division) as outward-rounded intervals. On a sub-interval [t0, t1]
the Bernstein coefficients are the blossom values B(t0,t0,t0), B(t0,t0,t1), B(t0,t1,t1),
B(t1,t1,t1), computed by de Casteljau steps with a different parameter per level (Farin,
"Curves and Surfaces for CAGD", ch. 3-4); by the convex hull property, f([t0, t1]) lies in the
hull of these four values. This range is tight to O(width^2), where a plain interval evaluation
of r . (p x q) over [t0, t1] overestimates by O(width) and rarely excludes anything.

For the thickness test, ``n(t) = p(t) x q(t)`` is a quadratic with Bernstein coefficients
p0 x q0, (p0 x q1 + p1 x q0) / 2, p1 x q1, so ``|n(t)| <= max`` of their norms on [0, 1].
"""
from __future__ import annotations

import math

import numba
import numpy as np

from fraytool.collision.interval import (
    iv_abs_max,
    iv_add,
    iv_mul,
    iv_scale_nonneg,
    iv_sub,
    round_up,
)


@numba.njit(cache=True, fastmath=False)
def _iv_cross(p: np.ndarray, q: np.ndarray, out_out: np.ndarray) -> None:
    """out = p x q for interval 3-vectors, arrays of shape (3, 2) holding (lo, hi)."""
    for k in range(3):
        k1 = (k + 1) % 3
        k2 = (k + 2) % 3
        al, ah = iv_mul(p[k1, 0], p[k1, 1], q[k2, 0], q[k2, 1])
        bl, bh = iv_mul(p[k2, 0], p[k2, 1], q[k1, 0], q[k1, 1])
        out_out[k, 0], out_out[k, 1] = iv_sub(al, ah, bl, bh)


@numba.njit(cache=True, fastmath=False)
def _iv_dot(r: np.ndarray, n: np.ndarray) -> tuple[float, float]:
    """r . n for interval 3-vectors of shape (3, 2)."""
    lo, hi = iv_mul(r[0, 0], r[0, 1], n[0, 0], n[0, 1])
    for k in range(1, 3):
        al, ah = iv_mul(r[k, 0], r[k, 1], n[k, 0], n[k, 1])
        lo, hi = iv_add(lo, hi, al, ah)
    return lo, hi


@numba.njit(cache=True, fastmath=False)
def _iv_norm_up(n: np.ndarray) -> float:
    """Upper bound of |x| over the interval 3-vector n (3, 2)."""
    sq = 0.0
    for k in range(3):
        m = iv_abs_max(n[k, 0], n[k, 1])
        sq = round_up(sq + round_up(m * m))
    return round_up(math.sqrt(sq))


@numba.njit(cache=True, fastmath=False)
def coplanarity_bernstein(ps: np.ndarray, pe: np.ndarray, coef_out: np.ndarray) -> float:
    """Interval Bernstein coefficients of 3 f(t) on [0, 1] and a bound on |p x q|.

    Args: ps, pe (4, 3) end points (a0, a1, b0, b1) at the step start / end [m];
    coef_out (4, 2) receives (lo, hi) of b_0..b_3 = 3 c_0..3 c_3 [m^3].
    Returns: N >= |p(t) x q(t)| for every t in [0, 1] [m^2], rounded up.
    """
    # vec[m] for m = p0, p1, q0, q1, r0, r1 (then 4 cross products), each (3, 2) intervals.
    vec = np.empty((10, 3, 2))
    ends = ((1, 0), (3, 2), (2, 0))  # p = a1 - a0, q = b1 - b0, r = b0 - a0
    for m in range(3):
        i, j = ends[m]
        for k in range(3):
            vec[2 * m, k, 0], vec[2 * m, k, 1] = iv_sub(ps[i, k], ps[i, k], ps[j, k], ps[j, k])
            vec[2 * m + 1, k, 0], vec[2 * m + 1, k, 1] = iv_sub(
                pe[i, k], pe[i, k], pe[j, k], pe[j, k]
            )
    p0, p1, q0, q1, r0, r1 = vec[0], vec[1], vec[2], vec[3], vec[4], vec[5]
    n00, n01, n10, n11 = vec[6], vec[7], vec[8], vec[9]  # p_i x q_j
    _iv_cross(p0, q0, n00)
    _iv_cross(p0, q1, n01)
    _iv_cross(p1, q0, n10)
    _iv_cross(p1, q1, n11)

    lo, hi = _iv_dot(r0, n00)
    coef_out[0, 0], coef_out[0, 1] = iv_scale_nonneg(3.0, lo, hi)
    al, ah = _iv_dot(r1, n00)
    bl, bh = _iv_dot(r0, n10)
    cl, ch = _iv_dot(r0, n01)
    lo, hi = iv_add(al, ah, bl, bh)
    coef_out[1, 0], coef_out[1, 1] = iv_add(lo, hi, cl, ch)
    al, ah = _iv_dot(r0, n11)
    bl, bh = _iv_dot(r1, n01)
    cl, ch = _iv_dot(r1, n10)
    lo, hi = iv_add(al, ah, bl, bh)
    coef_out[2, 0], coef_out[2, 1] = iv_add(lo, hi, cl, ch)
    lo, hi = _iv_dot(r1, n11)
    coef_out[3, 0], coef_out[3, 1] = iv_scale_nonneg(3.0, lo, hi)

    # n1 = (n01 + n10) / 2: |n1| <= (|n01| + |n10|) / 2
    mid = round_up(0.5 * round_up(_iv_norm_up(n01) + _iv_norm_up(n10)))
    return max(_iv_norm_up(n00), mid, _iv_norm_up(n11))


@numba.njit(cache=True, fastmath=False, inline="always")
def _iv_lerp(xl: float, xh: float, yl: float, yh: float, t: float) -> tuple[float, float]:
    """x + t (y - x) for intervals x, y and an exact t in [0, 1]."""
    dl, dh = iv_sub(yl, yh, xl, xh)
    ml, mh = iv_scale_nonneg(t, dl, dh)
    return iv_add(xl, xh, ml, mh)


@numba.njit(cache=True, fastmath=False)
def cubic_range(coef: np.ndarray, t0: float, t1: float) -> tuple[float, float]:
    """Interval containing the Bernstein cubic ``coef`` (4, 2) over [t0, t1], 0 <= t0 <= t1 <= 1.

    Hull of the blossom values B(t0,t0,t0), B(t0,t0,t1), B(t0,t1,t1), B(t1,t1,t1).
    """
    # level 1 at t0 (a*) and at t1 (b*)
    a0l, a0h = _iv_lerp(coef[0, 0], coef[0, 1], coef[1, 0], coef[1, 1], t0)
    a1l, a1h = _iv_lerp(coef[1, 0], coef[1, 1], coef[2, 0], coef[2, 1], t0)
    a2l, a2h = _iv_lerp(coef[2, 0], coef[2, 1], coef[3, 0], coef[3, 1], t0)
    b0l, b0h = _iv_lerp(coef[0, 0], coef[0, 1], coef[1, 0], coef[1, 1], t1)
    b1l, b1h = _iv_lerp(coef[1, 0], coef[1, 1], coef[2, 0], coef[2, 1], t1)
    b2l, b2h = _iv_lerp(coef[2, 0], coef[2, 1], coef[3, 0], coef[3, 1], t1)
    # level 2: (t0, t0), (t0, t1), (t1, t1)
    c0l, c0h = _iv_lerp(a0l, a0h, a1l, a1h, t0)
    c1l, c1h = _iv_lerp(a1l, a1h, a2l, a2h, t0)
    d0l, d0h = _iv_lerp(a0l, a0h, a1l, a1h, t1)
    d1l, d1h = _iv_lerp(a1l, a1h, a2l, a2h, t1)
    e0l, e0h = _iv_lerp(b0l, b0h, b1l, b1h, t1)
    e1l, e1h = _iv_lerp(b1l, b1h, b2l, b2h, t1)
    # level 3: B(t0,t0,t0), B(t0,t0,t1), B(t0,t1,t1), B(t1,t1,t1)
    w0l, w0h = _iv_lerp(c0l, c0h, c1l, c1h, t0)
    w1l, w1h = _iv_lerp(c0l, c0h, c1l, c1h, t1)
    w2l, w2h = _iv_lerp(d0l, d0h, d1l, d1h, t1)
    w3l, w3h = _iv_lerp(e0l, e0h, e1l, e1h, t1)
    return min(min(w0l, w1l), min(w2l, w3l)), max(max(w0h, w1h), max(w2h, w3h))
